// Memory bounds of a conversion: an estimate from the voxel count (checked before loading),
// and a hard address-space limit for the process (so a hostile or huge input fails with
// "out of memory" instead of taking the machine down).
#pragma once

#include <cstdint>
#include <string>

namespace typemerge::app {

// Peak memory of converting a series of `voxels` voxels: measured 393–515 MB peak RSS for the
// abdomen (35 M voxels, bone and skin; `/usr/bin/time -v typemerge convert`), i.e. about
// 14 bytes a voxel (the HU volume, its table-removed copy and masks, the meshes) plus the
// process itself; 16 bytes a voxel and 64 MiB leave a margin.
std::uint64_t conversion_memory_estimate(std::uint64_t voxels);

// Three quarters of the physical memory.
std::uint64_t default_memory_budget();

// "512M", "8G", "1.5T" (powers of 1024) or plain bytes; throws std::invalid_argument.
std::uint64_t parse_memory_size(const std::string& text);

// "350 MiB"
std::string format_megabytes(std::uint64_t bytes);

// RLIMIT_AS of this process; not applied under AddressSanitizer, whose shadow memory is
// terabytes of address space. Returns whether it was applied.
bool limit_address_space(std::uint64_t bytes);

}  // namespace typemerge::app
