// Bytes of a volume file: read with a size bound, and gzip streams inflated with an output
// bound, so that a reader never holds more than its header says the data needs.
//
// Errors are FileError with a one-line reason that names no file content (callers add the
// file's role, never its name, to what they show).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <stdexcept>
#include <vector>

namespace typemerge::volume_file {

class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

using Bytes = std::vector<std::uint8_t>;

// The file's first `max_bytes` bytes (all of it when shorter). Throws FileError when it cannot
// be opened or read.
Bytes read_file(const std::filesystem::path& path,
                std::size_t max_bytes = static_cast<std::size_t>(-1));

// Whether `bytes` start with the gzip magic (1f 8b).
bool is_gzip(std::span<const std::uint8_t> bytes);

// Inflates a gzip stream (members concatenated as gzip allows) until `max_bytes` bytes are out
// or the stream ends. Throws FileError when the stream is damaged (a bad header, bad data, a
// CRC mismatch) or ends early: truncated, before its end marker and before `max_bytes` bytes.
// Garbage after the last member is ignored.
Bytes gunzip(std::span<const std::uint8_t> compressed, std::size_t max_bytes);

// The same stream handed to `sink` in pieces of at most 1 MiB, in order (together, gunzip's
// bytes), instead of held whole; the same errors, thrown after the pieces before the damage.
void gunzip_into(std::span<const std::uint8_t> compressed, std::size_t max_bytes,
                 const std::function<void(std::span<const std::uint8_t>)>& sink);
// The same for a gzip file read in pieces of 1 MiB (the compressed file is not held whole
// either). Throws FileError also when the file cannot be opened.
void gunzip_file_into(const std::filesystem::path& path, std::size_t max_bytes,
                      const std::function<void(std::span<const std::uint8_t>)>& sink);

// The file's bytes as its content is: inflated when it starts with the gzip magic (read in
// pieces: gunzip_file_into), else raw, at most `max_bytes` either way.
Bytes read_maybe_gzip(const std::filesystem::path& path, std::size_t max_bytes);

}  // namespace typemerge::volume_file
