// Label mode of `convert`: a label map (NIfTI or NRRD of integer labels) or a segmentation
// (3D Slicer .seg.nrrd) → one closed, named, coloured surface per label.
//
// Steps: the labels and their index boxes in one pass per layer (label_census); for each
// label, its 0/1 indicator inside its box padded by the smoothing's support plus one voxel (so
// the surface never reaches the box's border and closes by itself); the indicator smoothed and
// clamped (below); the project's extractor at ½ + η (η = 1/256, below) with convert's
// pipeline (make_surface: algorithm tm by default, finishing, checks). Labels are made on
// --threads workers at once (label_surfaces.h: the same bytes for any thread count); all
// surfaces are made before any file is written.
//
// The field f of a label, on its box:
//   g = G_σ * I        the indicator I (1 on the label's voxels) smoothed by a Gaussian of σ mm;
//   f = max(g, ½ + δ)  on the label's voxels,  f = min(g, ½ − δ)  elsewhere  (δ = 1/64).
// Default σ: half the smallest voxel spacing. A voxel staircase is a pattern of period two
// voxels; a Gaussian of σ = ½ voxel keeps e^(−2π²σ²f²) of frequency f (cycles per voxel): 29 %
// of the staircase (f = ½) and 73 % of a feature four voxels across (f = ¼): terraces fade,
// structures two voxels thick stay. `--label-smoothing 0` gives f = I, the raw voxel surface.
//
// Guarantees, and why:
//  * every voxel of the label is inside the surface and every other voxel outside: the clamp
//    fixes the sign of f − ½ at every sample to the voxel's membership, so smoothing moves
//    the surface only along the grid edges it crosses (by less than a voxel) and never changes
//    which voxels it encloses. Hence a single voxel and a one-voxel-thick line keep a surface,
//    and the surface's topology is the extractor's on the voxel set.
//  * closed, manifold, oriented, no crossings: the extractor's guarantees on a field whose
//    level set stays inside the box (padding) — checked per label and reported.
//  * two labels of one layer do not overlap beyond the extractor's tolerance: I_A + I_B ≤ 1,
//    so g_A + g_B ≤ 1 (the Gaussian is linear and positive), and the clamp keeps f_A + f_B ≤ 1
//    at every sample (a raised f_A = ½ + δ meets f_B ≤ ½ − δ). On every grid edge and every cube
//    face the linear (bilinear) interpolants then satisfy the same sum, so the regions
//    {f_A ≥ ½ + η} and {f_B ≥ ½ + η} are disjoint there — strictly, since both would need a
//    sum of 1 + 2η: the extraction level is η above ½ so that a face whose saddle sits at
//    exactly ½ (a 2 × 2 checkerboard of A and B, where f_A + f_B = 1) is resolved "apart" for
//    both labels, never "joined" for both. With marching cubes (--algorithm mc) the surfaces
//    therefore touch at most; tm's merged polygons are within its ε = ½ voxel of those
//    triangles, so with tm one label's surface reaches at most ε into the other's (tests
//    measure both). Segments of different layers (overlapping segments, as a file can hold)
//    overlap as their voxels do.
//  * volume: across each exposed voxel face the surface crosses between the two voxel
//    centres, so its volume differs from voxel count × voxel volume by less than the exposed
//    face area × half the largest spacing (tested below 1,000 voxels); above, tests bound it
//    by 6 % (measured −2 to −3 % on balls of 1,300 and 2,100 voxels). Thin structures keep
//    their topology but little volume: a one-voxel line about a tenth of it with the default
//    σ (the raw surface, about half), a single voxel a speck.
//
// Memory: the label map (4 bytes a voxel a layer) plus, per label being made (at most one per
// thread), two fields of its padded box and a byte per box voxel, and every label's surface.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <optional>

#include "app/convert_command.h"
#include "app/label_census.h"
#include "core/volume.h"

namespace CLI {
class App;
}

namespace typemerge::app {

// --labels, --label-names, --label-smoothing on `command`; --labels excludes the surface
// group's --preset, --iso and --window.
void add_label_options(CLI::App& command, CLI::App& surface_group, ConvertOptions& options);

// Whether `convert` runs in label mode: --labels given, or the input is a segmentation file
// (a NRRD with 3D Slicer's Segment keys, as .seg.nrrd). Reads the input's header only.
bool label_mode_requested(const ConvertOptions& options);

int run_label_convert(const ConvertOptions& options, std::ostream& log);

namespace detail {
inline constexpr float kClampMargin = 1.0f / 64.0f;     // δ above
inline constexpr double kLabelIso = 0.5 + 1.0 / 256.0;  // ½ + η, η < δ: the clamp stays outside it
// The clamped, smoothed indicator of `label` in `layer` on the label's box padded by
// `pad` voxels (outside the layer: background). sigma_mm = 0: the indicator itself.
core::Volume label_field(const core::Volume& layer, std::int32_t label, const LabelExtent& extent,
                         double sigma_mm);
}  // namespace detail

}  // namespace typemerge::app
