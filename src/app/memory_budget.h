// Memory bounds of a conversion: an estimate from the voxel count (checked before loading),
// and a hard address-space limit for the process (so a hostile or huge input fails with
// "out of memory" instead of taking the machine down).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

namespace typemerge::app {

// What a conversion holds besides its grid, from its options: the surfaces are made at once,
// each with its mesh and extraction state; a window preset (a `hi` bound) meshes a field, one
// more volume of floats; --reduce-to / --max-error copy the mesh into OpenMesh; --hollow holds
// a distance field per surface.
struct ConversionShape {
  std::size_t surfaces = 1;
  std::size_t window_surfaces = 0;
  bool reduces = false;
  bool hollows = false;
};

// Address space a conversion of `voxels` voxels needs, an upper bound that --max-memory is
// checked against before loading (and that batch schedules by). Fitted to the smallest
// address-space limit (ulimit -v) under which `convert --threads 2` succeeded, on a synthetic
// 512 × 512 × 300 series (78.6 M voxels) and the abdomen (35.1 M), 2026-12-02:
//   bone 615 / 379 MiB, muscle (window) 1135 / 804, bone,skin 772 / 599,
//   bone,skin,muscle 1465 / 1135, bone --reduce-to 835 / 505, skin --hollow 3 1402 / 804;
// i.e. 4 bytes a voxel for the volume, about 2 more per surface (5 more for a window's field
// and its larger surface), and some 190 MiB of the process's own mappings (libraries, thread
// stacks, malloc arenas), 128 more per extra surface thread and 192 per window; plus a tenth.
// Every case above is covered, by 3 to 40 %. Surfaces far larger than a CT tissue's (noise meshed at its mean) can
// exceed it: then the address-space limit fails the conversion cleanly ("out of memory").
// (Until 2026-12-02 the estimate was 16 bytes a voxel + 64 MiB whatever the options: over
// twice what bone needs, and below what three presets with a window need.)
std::uint64_t conversion_memory_estimate(std::uint64_t voxels, const ConversionShape& shape = {});

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
