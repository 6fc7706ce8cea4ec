// Table removal (remove_outside_body, run-length masks) against its byte-mask oracle
// (OpenCV's morphology), in one run, on one thread unless told:
//   body_mask_bench [--series DIR] [--threads N] [--repeat R]
// Without --series: a synthetic body lying on a table, 512 × 512 × 134. Prints each one's
// median time, the time per 35 M voxels (issue 15's target: ≤ 150 ms on one thread), the ratio,
// and whether the outputs are equal voxel for voxel.
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <utility>
#include <vector>

#include "body_mask_oracle.h"
#include "dicom/series_loader.h"
#include "dicom/series_scan.h"
#include "preprocess/body_mask.h"
#include "preprocess_test_volumes.h"

namespace {

using namespace typemerge;

template <typename Step>
double median_ms(int repeat, const core::Volume& input, Step step, preprocess::StepResult& last) {
  std::vector<double> times;
  for (int r = 0; r < repeat; ++r) {
    core::Volume copy = input;  // copied and paged in before the clock starts
    const auto start = std::chrono::steady_clock::now();
    last = step(std::move(copy));
    times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() -
                                                              start)
                        .count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::string series;
  int threads = 1, repeat = 5;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--series") series = argv[i + 1];
    else if (key == "--threads") threads = std::atoi(argv[i + 1]);
    else if (key == "--repeat") repeat = std::max(1, std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "usage: body_mask_bench [--series DIR] [--threads N] [--repeat R]\n");
      return 2;
    }
  }
  core::Volume volume;
  if (series.empty()) {
    volume = preprocess::test::body_lying_on_a_table(512, 134);
    series = "synthetic body on a table";
  } else {
    dicom::ScanOptions options;
    options.geometry.spacing = dicom::SpacingPolicy::resample;
    const dicom::FolderScan scan = dicom::scan_folder(series, options);
    if (!scan.default_series) {
      std::fprintf(stderr, "no loadable series in %s\n", series.c_str());
      return 1;
    }
    volume = dicom::load_series(scan.series[*scan.default_series]).volume;
    volume.to_float();  // the byte-mask oracle reads floats
  }
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<std::size_t>(std::max(1, threads)));
  const double voxels = static_cast<double>(volume.size().voxels());
  std::printf("%s: %lld x %lld x %lld (%.1f M voxels), %d thread(s), median of %d (the input "
              "moved in, as the pipeline does)\n",
              series.c_str(), static_cast<long long>(volume.size().nx),
              static_cast<long long>(volume.size().ny), static_cast<long long>(volume.size().nz),
              voxels / 1e6, threads, repeat);
  preprocess::StepResult runs, bytes;
  const double runs_ms = median_ms(repeat, volume, [](core::Volume v) {
    return preprocess::remove_outside_body(std::move(v));
  }, runs);
  const double bytes_ms = median_ms(repeat, volume, [](core::Volume v) {
    return preprocess::oracle::remove_outside_body_with_byte_masks(std::move(v));
  }, bytes);
  const bool same = runs.volume.samples() == bytes.volume.samples() &&
                    runs.record.description == bytes.record.description;
  std::printf("run-length masks   %8.1f ms  (%6.1f ms per 35 M voxels)\n", runs_ms,
              runs_ms * 35e6 / voxels);
  std::printf("byte masks, OpenCV %8.1f ms  (%6.1f ms per 35 M voxels)\n", bytes_ms,
              bytes_ms * 35e6 / voxels);
  std::printf("ratio %.2f; outputs %s; %s\n", bytes_ms / runs_ms, same ? "equal" : "DIFFER",
              runs.record.description.c_str());
  return same ? 0 : 1;
}
