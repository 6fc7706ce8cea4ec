#include "app/batch_summary.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <stdexcept>
#include <tuple>

#include "app/version.h"
#include "io/atomic_file.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::ordered_json;

StudyStatus status_from(const std::string& name) {
  for (StudyStatus s : {StudyStatus::converted, StudyStatus::up_to_date, StudyStatus::failed,
                        StudyStatus::interrupted, StudyStatus::no_study, StudyStatus::no_ct}) {
    if (name == status_name(s)) return s;
  }
  throw std::runtime_error("unknown study status '" + name + "'");
}

// Rounded so that summaries compare equal when nothing but timing noise differs.
double rounded(double value, double unit) { return std::round(value / unit) * unit; }

ordered_json to_json(const StudyOutcome& o) {
  ordered_json surfaces = ordered_json::array();
  for (const SurfaceOutcome& s : o.surfaces) {
    surfaces.push_back({{"surface", s.surface}, {"file", s.file}, {"triangles", s.triangles},
                        {"volume_ml", rounded(s.volume_ml, 0.001)},
                        {"closed_manifold", s.closed_manifold},
                        {"reduce_to_met", s.reduce_to_met}});
  }
  ordered_json skipped = ordered_json::array();
  for (const SkippedFiles& k : o.skipped) {
    skipped.push_back({{"files", k.files}, {"reason", k.reason},
                       {"counts_as_failure", k.counts_as_failure}});
  }
  return {{"input", o.input},
          {"study", o.study},
          {"series", o.series},
          {"output", o.output_name},
          {"status", status_name(o.status)},
          {"reason", o.reason},
          {"skipped", skipped},
          {"surfaces", surfaces},
          {"warnings", o.warnings},
          {"seconds", rounded(o.seconds, 0.001)},
          {"cpu_seconds", rounded(o.cpu_seconds, 0.001)},
          {"peak_memory_mb", rounded(o.peak_memory_mb, 0.1)}};
}

StudyOutcome from_json(const ordered_json& j) {
  StudyOutcome o;
  o.input = j.at("input").get<std::string>();
  o.study = j.at("study").get<std::string>();
  o.series = j.at("series").get<std::string>();
  o.output_name = j.at("output").get<std::string>();
  o.status = status_from(j.at("status").get<std::string>());
  o.reason = j.at("reason").get<std::string>();
  if (j.contains("skipped")) {  // absent from records of versions before folders were listed
    for (const auto& k : j.at("skipped")) {
      o.skipped.push_back({k.at("files").get<std::size_t>(), k.at("reason").get<std::string>(),
                           k.at("counts_as_failure").get<bool>()});
    }
  }
  for (const auto& s : j.at("surfaces")) {
    o.surfaces.push_back({s.at("surface").get<std::string>(), s.at("file").get<std::string>(),
                          s.at("triangles").get<std::uint64_t>(), s.at("volume_ml").get<double>(),
                          s.at("closed_manifold").get<bool>(),
                          // absent from records made before --reduce-to was type merging's
                          !s.contains("reduce_to_met") || s.at("reduce_to_met").get<bool>()});
  }
  if (j.contains("warnings")) o.warnings = j.at("warnings").get<std::vector<std::string>>();
  o.seconds = j.at("seconds").get<double>();
  o.cpu_seconds = j.at("cpu_seconds").get<double>();
  o.peak_memory_mb = j.at("peak_memory_mb").get<double>();
  return o;
}

// RFC 4180: fields holding a comma, quote or line break are quoted, quotes doubled.
std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string number(double value, const char* format) {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

std::string csv_text(const std::vector<StudyOutcome>& outcomes) {
  std::string text =
      "input,study,series,output,status,reason,surfaces,files,triangles,volume_ml,"
      "closed_manifold,warnings,seconds,cpu_seconds,peak_memory_mb\n";
  for (const StudyOutcome& o : outcomes) {
    std::string surfaces, files, triangles, volumes, closed;
    for (const SurfaceOutcome& s : o.surfaces) {
      if (!surfaces.empty()) {
        for (std::string* list : {&surfaces, &files, &triangles, &volumes, &closed}) *list += ';';
      }
      surfaces += s.surface;
      files += s.file;
      triangles += std::to_string(s.triangles);
      volumes += number(s.volume_ml, "%.3f");
      closed += s.closed_manifold ? "yes" : "no";
    }
    std::string warnings;
    for (const std::string& w : o.warnings) {
      if (!warnings.empty()) warnings += " | ";
      warnings += w;
    }
    for (const std::string& field :
         {o.input, o.study, o.series, o.output_name, std::string(status_name(o.status)), o.reason,
          surfaces, files, triangles, volumes, closed, warnings}) {
      text += csv_field(field) + ",";
    }
    text += number(o.seconds, "%.3f") + "," + number(o.cpu_seconds, "%.3f") + "," +
            number(o.peak_memory_mb, "%.1f") + "\n";
  }
  return text;
}

void write_atomically(const fs::path& path, const std::string& text) {
  io::AtomicFile file(path);
  file.write(text);
  file.commit();
}

bool is_folder(const StudyOutcome& o) {
  return o.status == StudyStatus::no_study || o.status == StudyStatus::no_ct;
}

// Summaries list studies by output name, whatever order they were converted in, then the
// folders without a study by id.
void sort_by_output_name(std::vector<StudyOutcome>& outcomes) {
  std::sort(outcomes.begin(), outcomes.end(), [](const StudyOutcome& a, const StudyOutcome& b) {
    return std::make_tuple(is_folder(a), std::cref(a.output_name), std::cref(a.study),
                           std::cref(a.input)) <
           std::make_tuple(is_folder(b), std::cref(b.output_name), std::cref(b.study),
                           std::cref(b.input));
  });
}

}  // namespace

const char* status_name(StudyStatus status) {
  switch (status) {
    case StudyStatus::converted: return "converted";
    case StudyStatus::up_to_date: return "up_to_date";
    case StudyStatus::failed: return "failed";
    case StudyStatus::interrupted: return "interrupted";
    case StudyStatus::no_study: return "no_study";
    case StudyStatus::no_ct: return "no_ct";
  }
  return "failed";
}

std::string outcome_json(const StudyOutcome& outcome) { return to_json(outcome).dump(); }

StudyOutcome outcome_from_json(const std::string& json) {
  try {
    return from_json(ordered_json::parse(json));
  } catch (const nlohmann::json::exception& error) {
    throw std::runtime_error(std::string("malformed summary entry: ") + error.what());
  }
}

BatchTotals totals_of(const std::vector<StudyOutcome>& outcomes) {
  BatchTotals totals;
  for (const StudyOutcome& o : outcomes) {
    switch (o.status) {
      case StudyStatus::converted: ++totals.converted; break;
      case StudyStatus::up_to_date: ++totals.up_to_date; break;
      case StudyStatus::failed: ++totals.failed; break;
      case StudyStatus::interrupted: ++totals.interrupted; break;
      case StudyStatus::no_study: ++totals.no_study; break;
      case StudyStatus::no_ct: ++totals.no_ct; break;
    }
    if (o.status == StudyStatus::converted || o.status == StudyStatus::up_to_date) {
      for (const SurfaceOutcome& s : o.surfaces) totals.reduce_to_not_met += s.reduce_to_met ? 0 : 1;
    }
  }
  return totals;
}

void write_summary(const fs::path& out_root, const std::string& stem,
                   std::vector<StudyOutcome> outcomes, const std::string& shard) {
  sort_by_output_name(outcomes);
  const BatchTotals totals = totals_of(outcomes);
  ordered_json json = {{"tool", "typemerge"},
                       {"version", kVersion},
                       {"shard", shard},
                       {"studies", totals.studies()},
                       {"converted", totals.converted},
                       {"up_to_date", totals.up_to_date},
                       {"failed", totals.failed},
                       {"interrupted", totals.interrupted},
                       {"no_study", totals.no_study},
                       {"no_ct", totals.no_ct},
                       {"reduce_to_not_met", totals.reduce_to_not_met}};
  json["results"] = ordered_json::array();
  for (const StudyOutcome& o : outcomes) json["results"].push_back(to_json(o));
  write_atomically(out_root / (stem + ".json"), json.dump(2) + "\n");
  write_atomically(out_root / (stem + ".csv"), csv_text(outcomes));
}

std::vector<StudyOutcome> merge_shard_summaries(const fs::path& out_root) {
  static const std::regex kShardName(R"(summary\.shard-([0-9]+)-of-([0-9]+)\.json)");
  std::map<int, fs::path> shards;
  int count = 0;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(out_root, error)) {
    std::smatch match;
    const std::string name = entry.path().filename().string();
    if (!std::regex_match(name, match, kShardName)) continue;
    const int k = std::stoi(match[1]);
    const int n = std::stoi(match[2]);
    if (count != 0 && n != count) {
      throw std::runtime_error("shard summaries of different shard counts in " +
                               out_root.string() + " (" + std::to_string(count) + " and " +
                               std::to_string(n) + ")");
    }
    count = n;
    shards[k] = entry.path();
  }
  if (error) throw std::runtime_error("cannot read " + out_root.string());
  if (count == 0) throw std::runtime_error("no summary.shard-K-of-N.json in " + out_root.string());
  std::string missing;
  for (int k = 1; k <= count; ++k) {
    if (!shards.count(k)) missing += (missing.empty() ? "" : ", ") + std::to_string(k);
  }
  if (!missing.empty()) {
    throw std::runtime_error("shard summaries missing for shard(s) " + missing + " of " +
                             std::to_string(count));
  }
  std::vector<StudyOutcome> outcomes;
  std::map<std::string, int> seen;
  for (const auto& [k, path] : shards) {
    std::ifstream in(path);
    try {
      const ordered_json json = ordered_json::parse(in);
      for (const auto& result : json.at("results")) {
        outcomes.push_back(from_json(result));
        const StudyOutcome& o = outcomes.back();
        const std::string id = is_folder(o) ? o.input : "study " + o.study;
        if (seen[id]++ > 0) throw std::runtime_error(id + " appears in two shards");
      }
    } catch (const nlohmann::json::exception& e) {
      throw std::runtime_error("malformed " + path.filename().string() + ": " + e.what());
    }
  }
  sort_by_output_name(outcomes);
  write_summary(out_root, "summary", outcomes, "");
  return outcomes;
}

}  // namespace typemerge::app
