// Writes a Volume as a NRRD file (attached raw data) that 3D Slicer opens in place: the
// "space directions" are the exact index → LPS columns (sheared for a tilted gantry) and the
// "space origin" the centre of voxel (0,0,0), so what is shown is exactly what is meshed.
#pragma once

#include <filesystem>

#include "core/volume.h"

namespace typemerge::io {

enum class NrrdSampleType { int16, float32 };

// int16 rounds to the nearest HU and saturates; float32 keeps fractional values (from a
// non-integral rescale or resampling) exactly. Atomic; throws std::runtime_error.
void write_nrrd(const core::Volume& volume, const std::filesystem::path& path,
                NrrdSampleType type);

}  // namespace typemerge::io
