// Memory bounds of a conversion: an estimate from the voxel count (checked before loading),
// and a hard address-space limit for the process (so a hostile or huge input fails with
// "out of memory" instead of taking the machine down).
#pragma once

#include <array>
#include <cstdint>
#include <string>

namespace typemerge::app {

// Peak memory of converting a series of `voxels` voxels: measured 368 MB (abdomen) and 562 MB
// (head_tilt_variable resampled) peak RSS for 35 M voxels with bone and skin made concurrently
// (batch summary), i.e. up to about 15 bytes a voxel (the HU volume, its table-removed copy and
// masks, two meshes) plus the process itself; 16 bytes a voxel and 64 MiB (629 MB here) leave
// a thin margin.
std::uint64_t conversion_memory_estimate(std::uint64_t voxels);

// The voxels to pass to conversion_memory_estimate for a grid of `size` voxels spaced
// `spacing_mm` apart: the grid itself, plus, when --voxel-size resamples it
// (voxel_size_mm > 0), the resampled grid — both are held while resampling, and the surfaces
// are made from the second (0.5 mm voxels on a 0.8 × 0.8 × 1.25 mm CT: 13 times the voxels).
std::uint64_t working_voxels(const std::array<std::uint64_t, 3>& size,
                             const std::array<double, 3>& spacing_mm, double voxel_size_mm);

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
