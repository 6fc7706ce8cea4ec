// The batch manifest: one record per study in OUTDIR/.typemerge/studies/<study id>.json, written
// atomically after the study's outputs are in place. A rerun skips a study whose key (input
// content, tool version, parameters) and outputs are unchanged, and redoes the rest. One file per
// study keeps shards that share an output folder from ever writing the same file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace typemerge::app {

// A file as last seen: when size and modification time are unchanged, its content hash is
// taken from here instead of reading the file again (like make or git's index).
struct FileStamp {
  std::string path;  // hash of the file's path (folder names can spell patient names)
  std::uint64_t size = 0;
  std::int64_t mtime_ns = 0;
  std::uint64_t hash = 0;  // XXH3-64 of the content
};

struct StudyKey {
  std::string key;  // 16 hex digits
  std::vector<FileStamp> stamps;
};

// Content key of a study: XXH3 over the tool version, the conversion parameters and the sorted
// content hashes of its files (so renaming or moving files does not change it). `known` are the
// stamps of the previous run. Throws std::runtime_error when a file cannot be read.
StudyKey study_key(const std::vector<std::filesystem::path>& files, const std::string& parameters,
                   const std::vector<FileStamp>& known);

struct OutputFile {
  std::string path;  // relative to the output root, '/'-separated
  std::uint64_t size = 0;
};

struct StudyRecord {
  std::string study_id;
  std::string key;
  std::string output_name;
  std::vector<OutputFile> outputs;
  std::vector<FileStamp> stamps;
  std::string entry_json;  // the summary entry of the run that made the outputs
};

std::filesystem::path batch_state_folder(const std::filesystem::path& out_root);  // .typemerge

// nullopt when there is no record or it cannot be parsed (the study is then redone).
std::optional<StudyRecord> read_study_record(const std::filesystem::path& out_root,
                                             const std::string& study_id);
// Atomic; throws std::runtime_error on failure.
void write_study_record(const std::filesystem::path& out_root, const StudyRecord& record);
void remove_study_record(const std::filesystem::path& out_root, const std::string& study_id);

// Every output the record lists exists with the recorded size.
bool outputs_intact(const std::filesystem::path& out_root, const StudyRecord& record);

}  // namespace typemerge::app
