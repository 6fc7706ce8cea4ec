// A byte-level walk over a DICOM file that measures how deeply its sequences nest, before
// DCMTK parses it.
//
// DCMTK parses sequences recursively: a crafted file with tens of thousands of nested items
// overflows the stack (a crash, not an error). Real files nest a few levels; the walk reads
// only element headers (it seeks over values) and stops at the pixel data, so it costs a few
// small reads per file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace typemerge::dicom {

inline constexpr int kMaxSequenceDepth = 32;

struct NestingReport {
  int max_depth = 0;
  bool deflated = false;  // deflated data sets are inflated (bounded) and walked the same way
  std::string error;      // non-empty: the file must not be handed to DCMTK
  // Where the top-level pixel data value starts in the file and its declared length, when the
  // walk reached it (not for deflated data sets); lets the header check catch truncation.
  std::optional<std::uint64_t> pixel_data_offset;
  std::uint32_t pixel_data_length = 0;
};

NestingReport prescan_nesting(const std::filesystem::path& file, int max_depth = kMaxSequenceDepth);

}  // namespace typemerge::dicom
