#include "app/volume_file_input.h"

#include "app/exit_codes.h"
#include "nifti/nifti_reader.h"
#include "nrrd/nrrd_reader.h"

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
    } else {
      const nrrd::NrrdHeader header = nrrd::read_nrrd_header(path);
      shape.format = "NRRD";
      shape.size = header.size;
      shape.layers = header.layers;
      shape.geometry = header.geometry;
      shape.segmentation = header.segmentation;
      shape.type = header.type;
    }
  } catch (const nifti::ReadError& error) {
    throw CommandError{kExitInputRefused, error.what()};
  } catch (const nrrd::ReadError& error) {
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
  }
  return file;
}

}  // namespace typemerge::app
