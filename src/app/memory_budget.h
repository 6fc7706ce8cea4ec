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
// more volume of floats; --reduce-to holds the search's best surface beside the one being made
// (and --report the marching-cubes surface its distance is measured against); --hollow holds
// a distance field per surface.
struct ConversionShape {
  std::size_t surfaces = 1;
  std::size_t window_surfaces = 0;
  bool reduces = false;
  bool hollows = false;
  // The series loads as int16 samples (dicom::loads_as_int16): 2 bytes a voxel, not 4.
  bool int16_samples = false;
};

// Address space a conversion of `voxels` voxels needs, an upper bound that --max-memory is checked
// against before loading (and that batch schedules by): 1.1 × (bytes a voxel × voxels + fixed MiB),
// with 4 bytes a voxel for the volume (2 for int16 samples), 2 more per surface and 5 more per
// window (its field and larger surface), per surface 4 more with --reduce-to and 10 with --hollow;
// fixed: 192 MiB of the process's own mappings (libraries, thread stacks, malloc arenas), 128 per
// extra surface thread, 192 per window, per surface 192 with --reduce-to or --max-error (the
// collapses' reference surface, grids and queue grow with the surface, not the grid) and 192 with
// --hollow. The constants are fitted to the smallest address-space limit (ulimit -v) under which
// `convert --threads 2` succeeded, on CT series of 78.6 M and 35.1 M voxels for each of those
// options, and cover every case measured (the fit: docs/benchmarks.md, "Moved from headers and the
// README" and "2026-12-06"). Surfaces far larger than a CT tissue's (noise meshed at its mean) can
// exceed it: then the address-space limit fails the conversion cleanly ("out of memory").
std::uint64_t conversion_memory_estimate(std::uint64_t voxels, const ConversionShape& shape = {});

// The voxels to pass to conversion_memory_estimate for a grid of `size` voxels spaced
// `spacing_mm` apart: the grid itself, plus, when --voxel-size resamples it
// (voxel_size_mm > 0), the resampled grid — both are held while resampling, and the surfaces
// are made from the second (0.5 mm voxels on a 0.8 × 0.8 × 1.25 mm CT: 6.4 times the voxels).
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
