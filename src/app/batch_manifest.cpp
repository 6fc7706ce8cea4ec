#include "app/batch_manifest.h"

#include <nlohmann/json.hpp>
#include <xxhash.h>

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <stdexcept>

#include "app/version.h"
#include "io/atomic_file.h"

namespace typemerge::app {
namespace {

namespace fs = std::filesystem;
using nlohmann::ordered_json;

std::string hex64(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

std::uint64_t parse_hex64(const std::string& text) { return std::stoull(text, nullptr, 16); }

// XXH3 streams the file through a 1 MiB buffer: hashing runs at memory speed, far above the
// disk, so the content key costs one read of the study.
std::uint64_t hash_file(const fs::path& path) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) throw std::runtime_error("cannot read " + path.string());
  std::unique_ptr<XXH3_state_t, XXH_errorcode (*)(XXH3_state_t*)> state(XXH3_createState(),
                                                                        &XXH3_freeState);
  XXH3_64bits_reset(state.get());
  std::vector<char> buffer(1 << 20);
  for (;;) {
    const std::size_t got = std::fread(buffer.data(), 1, buffer.size(), file.get());
    if (got > 0) XXH3_64bits_update(state.get(), buffer.data(), got);
    if (got < buffer.size()) break;
  }
  if (std::ferror(file.get())) throw std::runtime_error("cannot read " + path.string());
  return XXH3_64bits_digest(state.get());
}

fs::path record_path(const fs::path& out_root, const std::string& study_id) {
  return batch_state_folder(out_root) / "studies" / (study_id + ".json");
}

}  // namespace

StudyKey study_key(const std::vector<fs::path>& files, const std::string& parameters,
                   const std::vector<FileStamp>& known) {
  std::map<std::string, const FileStamp*> by_path;
  for (const FileStamp& stamp : known) by_path[stamp.path] = &stamp;
  StudyKey key;
  std::vector<std::uint64_t> hashes;
  for (const fs::path& file : files) {
    struct stat info {};
    if (::stat(file.c_str(), &info) != 0) throw std::runtime_error("cannot read " + file.string());
    // The path is kept as a hash: input folder names can spell patient names.
    const std::string path = file.string();
    FileStamp stamp{hex64(XXH3_64bits(path.data(), path.size())), static_cast<std::uint64_t>(info.st_size),
                    std::int64_t(info.st_mtim.tv_sec) * 1000000000 + info.st_mtim.tv_nsec, 0};
    const auto previous = by_path.find(stamp.path);
    if (previous != by_path.end() && previous->second->size == stamp.size &&
        previous->second->mtime_ns == stamp.mtime_ns) {
      stamp.hash = previous->second->hash;
    } else {
      stamp.hash = hash_file(file);
    }
    hashes.push_back(stamp.hash);
    key.stamps.push_back(stamp);
  }
  std::sort(hashes.begin(), hashes.end());
  std::string text = std::string("typemerge ") + kVersion + "\n" + parameters + "\n";
  for (std::uint64_t hash : hashes) text += hex64(hash) + "\n";
  key.key = hex64(XXH3_64bits(text.data(), text.size()));
  return key;
}

fs::path batch_state_folder(const fs::path& out_root) { return out_root / ".typemerge"; }

std::optional<StudyRecord> read_study_record(const fs::path& out_root, const std::string& study_id) {
  std::ifstream in(record_path(out_root, study_id));
  if (!in) return std::nullopt;
  try {
    const ordered_json json = ordered_json::parse(in);
    StudyRecord record;
    record.study_id = json.at("study").get<std::string>();
    record.key = json.at("key").get<std::string>();
    record.output_name = json.at("output_name").get<std::string>();
    for (const auto& output : json.at("outputs")) {
      record.outputs.push_back({output.at("path").get<std::string>(),
                                output.at("size").get<std::uint64_t>()});
    }
    for (const auto& stamp : json.at("files")) {
      record.stamps.push_back({stamp.at("path").get<std::string>(),
                               stamp.at("size").get<std::uint64_t>(),
                               stamp.at("mtime_ns").get<std::int64_t>(),
                               parse_hex64(stamp.at("hash").get<std::string>())});
    }
    record.entry_json = json.at("entry").dump();
    if (record.study_id != study_id) return std::nullopt;
    return record;
  } catch (const std::exception&) {
    return std::nullopt;  // unreadable or from another version: the study is redone
  }
}

void write_study_record(const fs::path& out_root, const StudyRecord& record) {
  ordered_json json = {{"study", record.study_id}, {"key", record.key},
                       {"output_name", record.output_name}};
  json["outputs"] = ordered_json::array();
  for (const OutputFile& output : record.outputs) {
    json["outputs"].push_back({{"path", output.path}, {"size", output.size}});
  }
  json["files"] = ordered_json::array();
  for (const FileStamp& stamp : record.stamps) {
    json["files"].push_back({{"path", stamp.path}, {"size", stamp.size},
                             {"mtime_ns", stamp.mtime_ns}, {"hash", hex64(stamp.hash)}});
  }
  json["entry"] = ordered_json::parse(record.entry_json);
  const fs::path path = record_path(out_root, record.study_id);
  fs::create_directories(path.parent_path());
  io::AtomicFile file(path);
  file.write(json.dump(1) + "\n");
  file.commit();
}

void remove_study_record(const fs::path& out_root, const std::string& study_id) {
  std::error_code error;
  fs::remove(record_path(out_root, study_id), error);
}

bool outputs_intact(const fs::path& out_root, const StudyRecord& record) {
  for (const OutputFile& output : record.outputs) {
    std::error_code error;
    const auto size = fs::file_size(out_root / output.path, error);
    if (error || size != output.size) return false;
  }
  return !record.outputs.empty();
}

}  // namespace typemerge::app
