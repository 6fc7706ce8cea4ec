#include "dicom/series_scan.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <numeric>
#include <stdexcept>
#include <tuple>

#include <tbb/parallel_for.h>

namespace typemerge::dicom {
namespace {

namespace fs = std::filesystem;

// FNV-1a: a stable, dependency-free hash for short series ids. Not for security: the id only
// has to differ between series of one scan and stay the same across runs.
std::uint64_t fnv1a(const std::string& text, std::uint64_t hash = 1469598103934665603ull) {
  for (unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ull;
  }
  return hash;
}

std::string short_id(const std::string& key) {
  char text[16];
  std::snprintf(text, sizeof text, "s%08llx",
                static_cast<unsigned long long>(fnv1a(key) & 0xFFFFFFFFull));
  return text;
}

std::vector<fs::path> list_files(const fs::path& root, const ScanOptions& options,
                                 std::vector<std::string>& warnings) {
  std::vector<fs::path> files;
  std::error_code error;
  if (fs::is_regular_file(root, error)) return {root};
  auto directory_options = fs::directory_options::skip_permission_denied;
  if (options.follow_symlinks) directory_options |= fs::directory_options::follow_directory_symlink;
  fs::recursive_directory_iterator it(root, directory_options, error);
  if (error) {
    warnings.push_back("cannot read folder: " + error.message());
    return files;
  }
  bool depth_warned = false;
  for (; it != fs::recursive_directory_iterator(); it.increment(error)) {
    if (error) {
      warnings.push_back("cannot read part of the folder tree: " + error.message());
      break;
    }
    const fs::directory_entry& entry = *it;
    if (entry.is_symlink(error) && !options.follow_symlinks) {
      if (it.depth() == 0 || entry.is_directory(error)) it.disable_recursion_pending();
      continue;
    }
    if (entry.is_directory(error)) {
      if (it.depth() + 1 >= options.max_depth) {
        it.disable_recursion_pending();
        if (!depth_warned) {
          warnings.push_back("folders deeper than " + std::to_string(options.max_depth) +
                             " levels were not searched");
          depth_warned = true;
        }
      }
      continue;
    }
    if (!entry.is_regular_file(error)) continue;
    if (files.size() >= options.max_files) {
      warnings.push_back("stopped after " + std::to_string(options.max_files) + " files");
      break;
    }
    files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// Orientation clusters inside one series: slices whose row and column directions agree.
bool same_orientation(const SliceHeader& a, const SliceHeader& b, double tolerance) {
  core::Vec3 ra, ca, na, rb, cb, nb;
  if (!orientation_frame(*a.orientation, ra, ca, na) ||
      !orientation_frame(*b.orientation, rb, cb, nb)) {
    return *a.orientation == *b.orientation;
  }
  const double row_dot = ra[0] * rb[0] + ra[1] * rb[1] + ra[2] * rb[2];
  const double col_dot = ca[0] * cb[0] + ca[1] * cb[1] + ca[2] * cb[2];
  return row_dot > 1 - tolerance && col_dot > 1 - tolerance;
}

std::string spacing_key(const std::array<double, 2>& spacing) {
  char text[64];
  std::snprintf(text, sizeof text, "%.4g\\%.4g", spacing[0], spacing[1]);
  return text;
}

// ImageType values 1–3 (ORIGINAL/DERIVED, PRIMARY/SECONDARY, AXIAL/LOCALIZER) tell images
// apart; later values are vendor-specific (GE marks some slices of one series "ADD"), so
// they must not split a series.
std::string image_type_key(const std::string& image_type) {
  std::size_t end = 0;
  for (int separators = 0; end < image_type.size(); ++end) {
    if (image_type[end] == '\\' && ++separators == 3) break;
  }
  return image_type.substr(0, end);
}

}  // namespace

const SeriesInfo* FolderScan::find(const std::string& id) const {
  for (const SeriesInfo& info : series) {
    if (info.id == id) return &info;
  }
  return nullptr;
}

std::vector<SeriesInfo> group_into_series(std::vector<SliceHeader> headers,
                                          const GeometryOptions& options) {
  // Key without orientation: orientation is clustered with a tolerance below.
  using Key = std::tuple<std::string, std::string, std::string, int, int, std::string,
                         std::string>;
  std::map<Key, std::vector<SliceHeader>> by_key;
  for (SliceHeader& header : headers) {
    Key key{header.study_uid, header.series_uid, header.frame_of_reference_uid, header.rows,
            header.columns, spacing_key(*header.pixel_spacing), image_type_key(header.image_type)};
    by_key[key].push_back(std::move(header));
  }

  std::vector<SeriesInfo> series;
  for (auto& [key, members] : by_key) {
    std::vector<std::vector<SliceHeader>> clusters;
    for (SliceHeader& header : members) {
      auto cluster = std::find_if(clusters.begin(), clusters.end(), [&](const auto& c) {
        return same_orientation(c.front(), header, options.orientation_tolerance);
      });
      if (cluster == clusters.end()) {
        clusters.emplace_back();
        cluster = std::prev(clusters.end());
      }
      cluster->push_back(std::move(header));
    }
    // The largest cluster is the series; the others are orientation outliers (localizers).
    std::stable_sort(clusters.begin(), clusters.end(),
                     [](const auto& a, const auto& b) { return a.size() > b.size(); });
    for (std::size_t c = 0; c < clusters.size(); ++c) {
      SeriesInfo info;
      const SliceHeader& first = clusters[c].front();
      const auto& o = *first.orientation;
      char orientation_text[128];
      std::snprintf(orientation_text, sizeof orientation_text, "%.3f %.3f %.3f %.3f %.3f %.3f",
                    o[0], o[1], o[2], o[3], o[4], o[5]);
      info.id = short_id(std::get<0>(key) + "|" + std::get<1>(key) + "|" + std::get<2>(key) + "|" +
                         std::to_string(std::get<3>(key)) + "x" + std::to_string(std::get<4>(key)) +
                         "|" + std::get<5>(key) + "|" + std::get<6>(key) + "|" +
                         (c == 0 ? std::string() : orientation_text));
      info.description = first.series_description;
      info.modality = first.modality;
      info.convolution_kernel = first.convolution_kernel;
      info.series_number = first.series_number;
      info.rows = first.rows;
      info.columns = first.columns;
      if (first.is_localizer()) {
        info.role = SeriesRole::localizer;
        info.role_reason = "ImageType says LOCALIZER";
      } else if (c > 0) {
        info.role = SeriesRole::localizer;
        info.role_reason = "orientation differs from the rest of its series";
      }
      info.geometry = compute_stack_geometry(clusters[c], options);
      if (info.geometry.ok()) {
        for (std::size_t index : info.geometry.order) info.slices.push_back(clusters[c][index]);
      } else {
        info.slices = std::move(clusters[c]);  // refused: every image, for the report
      }
      series.push_back(std::move(info));
    }
  }
  std::sort(series.begin(), series.end(), [](const SeriesInfo& a, const SeriesInfo& b) {
    return std::tie(a.series_number, a.id) < std::tie(b.series_number, b.id);
  });
  return series;
}

std::optional<std::size_t> choose_series(
    const std::vector<SeriesInfo>& series, std::span<const std::size_t> candidates,
    const std::function<bool(const SeriesInfo&)>& eligible) {
  std::optional<std::size_t> best;
  for (const std::size_t s : candidates) {
    if (!series[s].usable() || !eligible(series[s])) continue;
    if (!best) {
      best = s;
      continue;
    }
    const SeriesInfo& a = series[s];
    const SeriesInfo& b = series[*best];
    if (a.slices.size() != b.slices.size()) {
      if (a.slices.size() > b.slices.size()) best = s;
    } else if (a.geometry.slice_step_mm < b.geometry.slice_step_mm - 1e-6) {
      best = s;
    }
  }
  return best;
}

std::optional<std::size_t> choose_series(
    const std::vector<SeriesInfo>& series,
    const std::function<bool(const SeriesInfo&)>& eligible) {
  std::vector<std::size_t> all(series.size());
  std::iota(all.begin(), all.end(), std::size_t{0});
  return choose_series(series, all, eligible);
}

std::optional<std::size_t> choose_default_series(const std::vector<SeriesInfo>& series) {
  return choose_series(series, [](const SeriesInfo&) { return true; });
}

FolderScan scan_folder(const fs::path& root, const ScanOptions& options) {
  std::error_code error;
  if (!fs::exists(root, error)) throw std::runtime_error("no such file or folder: " + root.string());
  FolderScan scan;
  scan.root = root;
  const std::vector<fs::path> files = list_files(root, options, scan.warnings);
  scan.files_seen = files.size();

  std::vector<SliceHeader> frames;
  std::map<std::string, std::vector<std::string>> warnings_by_series;
  // Headers are read in parallel (each file on its own), then merged in file order so the
  // result does not depend on scheduling.
  std::vector<HeaderReadResult> reads(files.size());
  tbb::parallel_for(std::size_t{0}, files.size(),
                    [&](std::size_t f) { reads[f] = read_headers(files[f], options.header); });
  for (std::size_t f = 0; f < files.size(); ++f) {
    const fs::path& file = files[f];
    HeaderReadResult& read = reads[f];
    const fs::path relative =
        fs::is_directory(root, error) ? file.lexically_relative(root) : file.filename();
    if (!read.skip_reason.empty()) {
      scan.skipped.push_back({relative, read.kind, read.skip_reason, read.refused_modality});
      continue;
    }
    for (SliceHeader& frame : read.frames) frames.push_back(std::move(frame));
    if (!read.warnings.empty() && !read.frames.empty()) {
      auto& list = warnings_by_series[read.frames.front().series_uid];
      for (auto& w : read.warnings) {
        if (std::find(list.begin(), list.end(), w) == list.end()) list.push_back(w);
      }
    }
  }
  scan.series = group_into_series(std::move(frames), options.geometry);
  for (SeriesInfo& info : scan.series) {
    if (!info.slices.empty()) {
      auto found = warnings_by_series.find(info.slices.front().series_uid);
      if (found != warnings_by_series.end()) info.warnings = found->second;
    }
  }
  scan.default_series = choose_default_series(scan.series);
  return scan;
}

}  // namespace typemerge::dicom
