// What batch tests compare between two runs of a batch: the outputs' bytes and the summaries
// without the figures that differ from run to run. Shared by the batch and the cluster tests.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "support/scratch_files.h"

namespace typemerge::test {

inline nlohmann::json summary_of(const std::filesystem::path& file) {
  return nlohmann::json::parse(read_file_bytes(file));
}

// The summary's results without what differs between runs (timings, memory).
inline nlohmann::json comparable(nlohmann::json results) {
  for (auto& r : results) {
    r.erase("seconds");
    r.erase("cpu_seconds");
    r.erase("peak_memory_mb");
    if (r["status"] == "up_to_date") r["status"] = "converted";
  }
  return results;
}

// Every file under `out` except the summaries, the manifest (.typemerge…) and any whose path
// starts with one of `also_skipped` (e.g. a scheduler's logs), with its bytes.
inline std::map<std::string, std::string> outputs_of(
    const std::filesystem::path& out, const std::vector<std::string>& also_skipped = {}) {
  std::map<std::string, std::string> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(out)) {
    const std::string relative = entry.path().lexically_relative(out).generic_string();
    bool skipped = !entry.is_regular_file() || relative.rfind(".typemerge", 0) == 0 ||
                   relative.rfind("summary", 0) == 0;
    for (const std::string& prefix : also_skipped) skipped |= relative.rfind(prefix, 0) == 0;
    if (!skipped) files[relative] = read_file_bytes(entry.path());
  }
  return files;
}

}  // namespace typemerge::test
