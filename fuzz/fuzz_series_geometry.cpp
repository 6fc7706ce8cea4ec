// Fuzz target: a few made-up slice headers through group_into_series (and so
// compute_stack_geometry), choose_default_series and load_series' checks before decoding.
//
// The bytes decode into 1–8 SliceHeaders as read_headers could return them: finite
// positions, orientations and spacings (the strict DS parser lets any finite value through,
// however large), positive spacings, a few UIDs, sizes and image types so that slices group,
// collide, duplicate and stack. Positions are mostly a base plus a whole number of steps (so
// regular, gapped and tilted stacks are common) with optional jitter.
//
// Properties (a violation aborts): a series that passes geometry has every ordered slice,
// at least two grid slices, finite grid axes with a non-zero determinant; the default series
// is usable; load_series either refuses with LoadError or (the files do not exist) fails to
// decode with LoadError — never another exception, never an allocation beyond its limit.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "fuzz_input.h"

namespace {

using namespace typemerge::dicom;
using typemerge::fuzz::FuzzInput;

[[noreturn]] void violated(const char* property) {
  std::fprintf(stderr, "fuzz_series_geometry: property violated: %s\n", property);
  std::abort();
}

// Mostly small, readable millimetres; sometimes any finite double.
double real(FuzzInput& in) {
  const unsigned mode = in.pick(8);
  if (mode == 0) return in.finite_double();
  if (mode == 1) return static_cast<double>(in.raw<std::int16_t>()) * 1e-4;
  return static_cast<double>(static_cast<std::int8_t>(in.byte())) * 0.5;
}

double positive(FuzzInput& in) {
  double value = std::abs(real(in));
  return value > 0 ? value : 0.5;
}

std::array<double, 6> orientation(FuzzInput& in) {
  switch (in.pick(6)) {
    case 0: return {1, 0, 0, 0, 1, 0};
    case 1: return {1, 0, 0, 0, 0, -1};  // coronal
    case 2: return {0, 1, 0, 0, 0, -1};  // sagittal
    case 3: return {1, 0, 0, 0, 0.9659258, -0.2588190};  // tilted by 15 degrees
    case 4: return {1, 0, 0, 0, 1, 0.0005};              // within tolerance
    default: {
      std::array<double, 6> o{};
      for (double& v : o) v = real(in);
      return o;
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzInput in(data, size);
  GeometryOptions options;
  options.spacing = in.flag() ? SpacingPolicy::resample : SpacingPolicy::refuse;

  const std::array<double, 6> common_orientation = orientation(in);
  const std::array<double, 2> common_spacing{positive(in), positive(in)};
  const Vec3 base{real(in), real(in), real(in)};
  const Vec3 step{real(in), real(in), real(in)};
  static constexpr std::uint16_t kSizes[] = {1, 2, 16, 512, 65535};
  static constexpr const char* kImageTypes[] = {"ORIGINAL\\PRIMARY\\AXIAL",
                                                "ORIGINAL\\PRIMARY\\LOCALIZER",
                                                "DERIVED\\SECONDARY\\AXIAL"};

  std::vector<SliceHeader> headers(1 + in.pick(8));
  for (SliceHeader& h : headers) {
    const unsigned variant = in.byte();
    h.kind = FileKind::ct_image;
    h.modality = "CT";
    h.study_uid = (variant & 1) ? "1.2" : "1.1";
    h.series_uid = (variant & 2) ? "1.2.3" : "1.2.4";
    h.frame_of_reference_uid = "1.3";
    h.image_type = kImageTypes[in.pick(3)];
    h.series_number = static_cast<std::int32_t>(in.pick(3));
    h.path = "/nonexistent/typemerge_fuzz/f" + std::to_string(in.pick(4));
    h.frames_in_file = 1 + in.pick(2);
    h.frame = in.pick(h.frames_in_file);
    h.sop_instance_uid = "1.4." + std::to_string(in.pick(4));
    h.rows = (variant & 4) ? kSizes[in.pick(5)] : 16;
    h.columns = (variant & 8) ? kSizes[in.pick(5)] : 16;
    h.bits_allocated = 16;
    h.bits_stored = 12;
    h.high_bit = 11;
    h.photometric = "MONOCHROME2";
    h.orientation = (variant & 16) ? orientation(in) : common_orientation;
    h.pixel_spacing = (variant & 32) ? std::array<double, 2>{positive(in), positive(in)}
                                     : common_spacing;
    const double k = static_cast<double>(in.pick(16));
    Vec3 position{base[0] + k * step[0], base[1] + k * step[1], base[2] + k * step[2]};
    if (variant & 64) {
      for (double& c : position) c += real(in);
    }
    for (double& c : position) c = std::isfinite(c) ? c : 0.0;  // as parsed: always finite
    h.position = position;
    h.rescale_slope = 1;
    h.rescale_intercept = -1024;
    h.has_rescale = true;
  }

  const std::vector<SeriesInfo> series = group_into_series(headers, options);
  for (const SeriesInfo& info : series) {
    const StackGeometry& g = info.geometry;
    if (!info.usable()) continue;
    if (g.order.size() != info.slices.size() || g.positions.size() != g.order.size() ||
        g.normal_offsets.size() != g.order.size()) {
      violated("ordered slices, positions and offsets disagree");
    }
    if (g.output_slices < 2) violated("a usable series with fewer than two grid slices");
    if (!g.needs_resampling && g.output_slices != static_cast<std::int64_t>(g.order.size())) {
      violated("grid slices differ from acquired slices without resampling");
    }
    for (const auto& axis : g.index_to_patient.axes) {
      for (double c : axis) {
        if (!std::isfinite(c)) violated("a grid axis is not finite");
      }
    }
    if (!(g.slice_step_mm > 0)) violated("a usable series with a slice step that is not positive");
    if (!(std::isfinite(g.tilt_degrees))) violated("tilt is not finite");

    LoadOptions load;
    load.max_volume_bytes = std::uint64_t{1} << 20;
    try {
      (void)load_series(info, load);
      violated("load_series decoded files that do not exist");
    } catch (const LoadError&) {
      // Refused by size, or the files cannot be read: both are messages.
    } catch (...) {
      violated("load_series threw something other than LoadError");
    }
  }
  if (const auto chosen = choose_default_series(series)) {
    if (*chosen >= series.size() || !series[*chosen].usable()) {
      violated("the default series is not a usable one");
    }
  }
  return 0;
}
