#include "app/volume_file_input.h"

#include <algorithm>

#include "app/exit_codes.h"
#include "nifti/nifti_reader.h"
#include "nrrd/nrrd_reader.h"
#include "seg/seg_reader.h"

namespace typemerge::app {

VolumeFileShape read_volume_file_shape(const std::filesystem::path& path, InputKind kind) {
  VolumeFileShape shape;
  try {
    if (kind == InputKind::nifti) {
      const nifti::NiftiHeader header = nifti::read_header(path);
      shape.format = "NIfTI-" + std::to_string(header.version);
      shape.size = header.size;
      shape.geometry = header.geometry;
      shape.segmentation = header.intent_label;
      shape.type = header.type;
      shape.int16_samples =
          volume_file::int16_by_type(header.type, header.slope, header.inter).value_or(false);
    } else if (kind == InputKind::seg) {
      // The label layers are known only once overlaps are found: the estimate counts one.
      const seg::SegHeader header = seg::read_seg_header(path);
      shape.format = "DICOM SEG";
      shape.size = header.size;
      shape.geometry = header.geometry;
      shape.segmentation = true;
      shape.type = volume_file::SampleType::uint16;
    } else {
      const nrrd::NrrdHeader header = nrrd::read_nrrd_header(path);
      shape.format = "NRRD";
      shape.size = header.size;
      shape.layers = header.layers;
      shape.geometry = header.geometry;
      shape.segmentation = header.segmentation;
      shape.type = header.type;
      shape.int16_samples = volume_file::int16_by_type(header.type, 1.0, 0.0).value_or(false);
    }
  } catch (const nifti::ReadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  } catch (const nrrd::ReadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  } catch (const seg::SegError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  return shape;
}

VolumeFile read_volume_file(const std::filesystem::path& path, InputKind kind,
                            std::uint64_t max_volume_bytes) {
  VolumeFile file;
  file.shape = read_volume_file_shape(path, kind);
  try {
    if (kind == InputKind::nifti) {
      nifti::ReadOptions options;
      options.max_volume_bytes = max_volume_bytes;
      nifti::NiftiImage image = nifti::read_nifti(path, options);
      file.values = image.values;
      file.warnings = std::move(image.warnings);
      file.content.layers.push_back(std::move(image.volume));
    } else if (kind == InputKind::seg) {
      seg::SegReadOptions options;
      options.max_volume_bytes = max_volume_bytes;
      seg::SegVolume volume = seg::read_seg(path, options);
      file.warnings = std::move(volume.warnings);
      file.content = std::move(volume.labels);
      file.shape.layers = file.content.layers.size();
      for (const core::Segment& segment : file.content.segments) {
        file.values.max = std::max(file.values.max, static_cast<float>(segment.label));
      }
    } else {
      nrrd::ReadOptions options;
      options.max_volume_bytes = max_volume_bytes;
      nrrd::NrrdImage image = nrrd::read_nrrd(path, options);
      file.values = image.values;
      file.warnings = std::move(image.warnings);
      file.content = nrrd::to_label_volume(std::move(image));
    }
  } catch (const nifti::ReadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  } catch (const nrrd::ReadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  } catch (const seg::SegError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  }
  return file;
}

}  // namespace typemerge::app
