#include "core/type_merging.h"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <numbers>
#include <span>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/huge_pages.h"
#include "core/merge/blocks.h"
#include "core/merge/piece_merge.h"
#include "core/parallel.h"

namespace typemerge::core {

MergeStats& MergeStats::operator+=(const MergeStats& part) {
  triangles_before += part.triangles_before;
  vertices_before += part.vertices_before;
  triangles_after += part.triangles_after;
  vertices_after += part.vertices_after;
  for (std::size_t k = 0; k < blocks_merged.size(); ++k) blocks_merged[k] += part.blocks_merged[k];
  rejected_topology += part.rejected_topology;
  rejected_facing += part.rejected_facing;
  rejected_flatness += part.rejected_flatness;
  rejected_outline += part.rejected_outline;
  rejected_separation += part.rejected_separation;
  blocks_demoted += part.blocks_demoted;
  blocks_split += part.blocks_split;
  face_vertices_removed += part.face_vertices_removed;
  face_vertices_restored += part.face_vertices_restored;
  triangulation_passes += part.triangulation_passes;
  tested_triangles += part.tested_triangles;
  tested_triangles_failed += part.tested_triangles_failed;
  tested_loop_vertices += part.tested_loop_vertices;
  tested_loop_vertices_failed += part.tested_loop_vertices_failed;
  return *this;
}


namespace detail {

// Where the pieces start and end, in cube layers: about layers / slab_layers pieces (an even
// number where more than one), cut where the surface estimated below them is equal, so that
// pieces cost about the same. Bone lies in a few slices: equal heights gave one abdomen
// piece three times the surface of another, and two threads waited on it (1.65× one thread's
// speed at 300 HU). The estimate counts, in every 8th row, the cut lattice edges a layer makes
// vertices on (about one boundary cube each): along x and y in its upper slice and along z
// between its two slices, where a padding slice (close_borders) is outside everywhere, so the
// caps that close a body cut by the volume's ends count as the large flat surfaces they are
// (counting x-edges alone missed them: the synthetic body at −500 HU scaled 1.51× on two
// threads, its first and last pieces holding most of the surface); plus one per layer. It
// depends on the volume alone, so the cuts (and the output) are the same for every thread
// count. Where pieces are at least two blocks high, cuts fall on multiples of the blocks' edge
// along z (block_dims: 4 on 3 mm slices over 1 mm pixels, else block_cubes), so every piece
// but the last is whole blocks high. (Multiples of block_cubes, 8 layers, left the abdomen's
// four pieces at 25 / 29 / 23 / 28 k of estimated work at 300 HU and 74 / 78 / 74 / 88 k at
// −500 HU: their times on one thread, 95 / 126 / 100 / 98 and 206 / 194 / 182 / 283 ms, capped
// two threads at 1.87 and 1.77 times one.)
std::vector<std::int64_t> piece_bounds(const Volume& volume, float iso, const ExtractOptions& extract,
                                       const MergeOptions& options, std::int64_t layers,
                                       unsigned threads, std::vector<double>* vertices) {
  if (vertices != nullptr) vertices->clear();
  if (layers <= 0) return {};
  if (options.slab_layers == 0 || options.slab_layers >= layers) return {0, layers};
  // An even count where there are layers for it: on two threads (the usual count, and this
  // project's test machines') pieces of equal work then end together. Nine pieces of the
  // 300-slice synthetic body kept one thread working alone on the ninth, which capped two
  // threads at 9 / 5 = 1.8 times one (measured 1.76–1.82).
  std::int64_t count = std::max<std::int64_t>(
      1, (2 * layers + options.slab_layers) / (2 * static_cast<std::int64_t>(options.slab_layers)));
  if (count > 1 && count % 2 != 0 && count < layers) ++count;
  const VolumeSize& size = volume.size();
  // Per slice k, in its sampled rows: cut x- and y-edges, inside samples, and cut z-edges to
  // slice k + 1.
  struct SliceCuts {
    std::uint64_t in_plane = 0;
    std::uint64_t inside = 0;
    std::uint64_t to_next = 0;
  };
  std::vector<SliceCuts> cuts(static_cast<std::size_t>(size.nz));
  // Every 8th row: the hardware's prefetch fetches the rest of each page a sampled row starts,
  // so sampling every 4th row of 512 int16 samples (a quarter page) read the whole volume,
  // 8.8 of an abdomen extraction's 240 ms at 300 HU, as long on two threads as on one (memory
  // bound); every 8th row reads half of it, in 3.0 ms.
  constexpr std::int64_t kRowStep = 8;
  detail::run_parallel(cuts.size(), threads, [&](std::size_t k, unsigned) {
    const auto z = static_cast<std::int64_t>(k);
    // Either storage: an int16 sample compares with iso as the float of the same integer.
    volume.visit([&](const auto* samples) {
      using Sample = std::remove_cv_t<std::remove_pointer_t<decltype(samples)>>;
      const std::size_t slice_size = static_cast<std::size_t>(size.nx * size.ny);
      const Sample* slice = samples + slice_size * k;
      const Sample* next = z + 1 < size.nz ? slice + slice_size : nullptr;
      // One plain loop per count, without a branch inside, so the compiler vectorises them
      // (the single loop with its three conditions was 6 % of an abdomen extraction at 300 HU).
      // int16 samples compare with ⌈iso⌉ as an int16 (the same answer, twice the samples a
      // vector step of float's); a threshold above every int16 is one no sample reaches.
      Sample threshold;
      if constexpr (std::is_same_v<Sample, float>) {
        threshold = iso;
      } else {
        const std::int32_t t = int16_threshold(iso);
        if (t > std::numeric_limits<std::int16_t>::max()) {
          cuts[k] = {};
          return;
        }
        threshold = static_cast<Sample>(t);
      }
      // Counted in lanes as wide as the samples, over chunks whose count a lane holds: the
      // comparisons' masks add without being widened (int16 samples: half the instructions).
      using Lane = std::conditional_t<sizeof(Sample) == 2, std::uint16_t, std::uint32_t>;
      auto count_flags = [](std::int64_t n, auto flag) {
        constexpr std::int64_t kChunk = 32768;
        std::uint32_t found = 0;
        for (std::int64_t first = 0; first < n; first += kChunk) {
          const std::int64_t last = std::min(n, first + kChunk);
          Lane part = 0;
          for (std::int64_t i = first; i < last; ++i) part = static_cast<Lane>(part + flag(i));
          found += part;
        }
        return found;
      };
      auto inside = [&](const Sample* p, std::int64_t n) {
        return count_flags(n, [&](std::int64_t i) { return Lane{p[i] >= threshold}; });
      };
      auto changes = [&](const Sample* p, const Sample* q, std::int64_t n) {
        return count_flags(n, [&](std::int64_t i) {
          return Lane{(p[i] >= threshold) != (q[i] >= threshold)};
        });
      };
      SliceCuts out;
      // The rows read next (two of this slice, one of the next), fetched while these are
      // counted: a sampled row starts a new page, where the hardware's prefetch stops.
      auto fetch = [&](const Sample* first, std::int64_t count_of) {
        const auto* bytes = reinterpret_cast<const char*>(first);
        const auto length = static_cast<std::size_t>(count_of) * sizeof(Sample);
        for (std::size_t at = 0; at < length; at += 64) __builtin_prefetch(bytes + at);
      };
      for (std::int64_t j = 0; j < size.ny; j += kRowStep) {
        const Sample* row = slice + j * size.nx;
        if (j + kRowStep < size.ny) {
          fetch(row + kRowStep * size.nx, std::min<std::int64_t>(2, size.ny - j - kRowStep) * size.nx);
          if (next != nullptr) fetch(next + (j + kRowStep) * size.nx, size.nx);
        }
        out.inside += inside(row, size.nx);
        out.in_plane += changes(row, row + 1, size.nx - 1);
        if (j + 1 < size.ny) out.in_plane += changes(row, row + size.nx, size.nx);
        if (next != nullptr) out.to_next += changes(row, next + j * size.nx, size.nx);
      }
      cuts[k] = out;
    });
  });
  // Layer L joins padded slices L and L + 1, i.e. volume slices L − pad and L + 1 − pad.
  const std::int64_t pad = extract.close_borders ? 1 : 0;
  auto is_slice = [&](std::int64_t k) { return k >= 0 && k < size.nz; };
  auto layer_work = [&](std::int64_t l) {
    const std::int64_t lower = l - pad;
    const std::int64_t upper = l + 1 - pad;
    std::uint64_t work = 1;
    if (is_slice(upper)) work += cuts[static_cast<std::size_t>(upper)].in_plane;
    if (is_slice(lower) && is_slice(upper)) {
      work += cuts[static_cast<std::size_t>(lower)].to_next;
    } else if (is_slice(lower) || is_slice(upper)) {
      work += cuts[static_cast<std::size_t>(is_slice(lower) ? lower : upper)].inside;
    }
    return work;
  };
  std::vector<std::uint64_t> before(static_cast<std::size_t>(layers) + 1, 0);  // work below L
  for (std::int64_t l = 0; l < layers; ++l) {
    before[static_cast<std::size_t>(l) + 1] = before[static_cast<std::size_t>(l)] + layer_work(l);
  }
  const std::uint64_t total = before.back();
  const std::int64_t block_z = merge::block_dims(volume.geometry(), options)[2];
  const std::int64_t snap = layers / count >= 2 * block_z ? block_z : 1;
  std::vector<std::int64_t> bounds{0};
  for (std::int64_t k = 1; k < count; ++k) {
    const std::uint64_t target = total * static_cast<std::uint64_t>(k) / static_cast<std::uint64_t>(count);
    std::int64_t cut = std::lower_bound(before.begin(), before.end(), target) - before.begin();
    // The multiple of snap below or above, whichever's work is nearer the target (the nearer
    // layer left the abdomen's −500 HU pieces at 83 / 68 / 74 / 88 k of estimated work).
    const std::int64_t down = std::min(cut / snap * snap, layers);
    const std::int64_t up = std::min(down + snap, layers);
    auto miss = [&](std::int64_t c) {
      const std::uint64_t work = before[static_cast<std::size_t>(c)];
      return work > target ? work - target : target - work;
    };
    cut = miss(up) < miss(down) ? up : down;
    // Every piece keeps at least one layer, and `count` pieces there are.
    bounds.push_back(std::clamp(cut, bounds.back() + 1, layers - (count - k)));
  }
  bounds.push_back(layers);
  if (vertices != nullptr) {
    for (std::size_t k = 0; k + 1 < bounds.size(); ++k) {
      const std::uint64_t work = before[static_cast<std::size_t>(bounds[k + 1])] -
                                 before[static_cast<std::size_t>(bounds[k])];
      vertices->push_back(static_cast<double>(work) * static_cast<double>(kRowStep));
    }
  }
  return bounds;
}

}  // namespace detail

TriangleMesh extract_type_merged(const Volume& volume, float iso, const ExtractOptions& extract,
                                  const MergeOptions& options, MergeStats* stats) {
  if (options.block_cubes < 2 || options.block_cubes > 32 ||
      !std::has_single_bit(options.block_cubes) || !(options.epsilon_voxels >= 0.0) ||
      !(options.epsilon_mm >= 0.0) || !std::isfinite(options.epsilon_mm)) {
    throw std::invalid_argument(
        "type merging: block_cubes must be a power of two from 2 to 32, epsilon_voxels >= 0 and "
        "epsilon_mm finite and >= 0");
  }
  // A block's loop is found as its edges on the block's faces, which holds only where every
  // other edge has a triangle on each side: classic mode's holes break that.
  if (extract.mode != ExtractOptions::Mode::consistent) {
    throw std::invalid_argument("type merging needs consistent marching cubes");
  }
  if (extract.stats != nullptr) *extract.stats = {};
  MergeStats total;
  TriangleMesh out;
  const std::int64_t layers = detail::cube_layer_count(volume, iso, extract);
  const unsigned threads = std::max(detail::resolve_threads(options.threads),
                                    detail::resolve_threads(extract.threads));
  // The estimate that cut the pieces also sizes their marching cubes' outputs, all for the
  // largest piece (sampling the layers again for that was 3.5 % of an abdomen extraction's
  // instructions at 300 HU).
  std::vector<double> expected_vertices;
  const std::vector<std::int64_t> bounds =
      detail::piece_bounds(volume, iso, extract, options, layers, threads, &expected_vertices);
  const std::size_t count = bounds.empty() ? 0 : bounds.size() - 1;
  // Pieces are appended in order as soon as their predecessors are; the output is reserved
  // ahead from the pieces so far (their average × the pieces in all, plus a fifth), so it is
  // not copied by doubling at its largest.
  std::vector<merge::VertexId> seam;
  // Scratch for the pieces being merged: taken while one is, given back after (at most one
  // per thread exists; freed after the last pieces, while the output is at its largest), with
  // the mesh arrays of pieces already appended. Every piece reserves for the largest estimate,
  // so a thread's scratch is not outgrown (and its pages faulted anew) by a later piece.
  std::mutex scratch_mutex;
  std::vector<std::unique_ptr<merge::PieceScratch>> spare;
  std::vector<TriangleMesh> spent;
  std::size_t started = 0;
  // The volume's slices each piece reads (slices_done): piece i's cube layers [b_i, b_i+1)
  // read slices b_i − pad to b_i+1 − pad, and one more on each side for gradient normals.
  // Its own slices, read by no other piece, are reported as soon as it has read them (as its
  // marching cubes passes them); the slices below the next piece's first as the pieces are
  // appended, in order, but for those.
  const std::int64_t pad = extract.close_borders ? 1 : 0;
  const std::int64_t nz = volume.size().nz;
  const auto first_read = [&](std::size_t i) {
    return std::max<std::int64_t>(0, bounds[i] - pad - 1);
  };
  const auto own_slices = [&](std::size_t i) {
    const std::int64_t begin = i == 0 ? 0 : std::min(nz, bounds[i] - pad + 2);
    const std::int64_t end = i + 1 < count ? first_read(i + 1) : nz;
    return std::pair{begin, std::max(begin, end)};
  };
  std::int64_t reported = 0;  // the slices below, but for later pieces' own, are reported
  const double largest =
      expected_vertices.empty()
          ? -1.0
          : *std::max_element(expected_vertices.begin(), expected_vertices.end());
  detail::make_in_order<merge::MergedPiece>(
      count, threads,
      [&](std::size_t i) {
        std::unique_ptr<merge::PieceScratch> scratch;
        TriangleMesh output;
        {
          const std::lock_guard lock(scratch_mutex);
          ++started;
          if (!spare.empty()) {
            scratch = std::move(spare.back());
            spare.pop_back();
          }
          if (!spent.empty()) {
            output = std::move(spent.back());
            spent.pop_back();
          }
        }
        if (!scratch) scratch = std::make_unique<merge::PieceScratch>();
        scratch->output = std::move(output);
        scratch->keep = i + threads < count;  // else this thread's last piece
        // Its own slices reported as it passes them, each once, in runs of at least
        // kReportRun slices (the last may be shorter): a page that straddles two reports is
        // not returned, and with one slice a report a small slice could lose every page.
        std::function<void(std::int64_t)> reads_below;
        if (options.slices_done) {
          reads_below = [&, own = own_slices(i), done = own_slices(i).first](
                            std::int64_t below) mutable {
            constexpr std::int64_t kReportRun = 2;
            const std::int64_t up_to = std::min(below, own.second);
            if (done < up_to && (up_to - done >= kReportRun || up_to == own.second)) {
              options.slices_done(done, up_to);
              done = up_to;
            }
          };
        }
        merge::MergedPiece piece = merge::merge_piece(volume, iso, extract, options, bounds[i],
                                                      bounds[i + 1], *scratch, largest,
                                                      reads_below);
        if (scratch->keep) {  // else freed now: the last pieces need no more
          const std::lock_guard lock(scratch_mutex);
          spare.push_back(std::move(scratch));
        }
        return piece;
      },
      [&](std::size_t i, merge::MergedPiece& piece) {
        const std::size_t vertices =
            out.positions.size() + piece.mesh.positions.size() - piece.shared;
        const std::size_t triangles = out.triangles.size() + piece.mesh.triangles.size();
        if (vertices > out.positions.capacity() || triangles > out.triangles.capacity()) {
          const double scale = 1.2 * static_cast<double>(count) / static_cast<double>(i + 1);
          const auto ahead = [&](std::size_t n) {
            return std::max(n, static_cast<std::size_t>(scale * static_cast<double>(n)));
          };
          detail::reserve_on_huge_pages(out.positions, ahead(vertices));
          if (extract.vertex_normals) detail::reserve_on_huge_pages(out.normals, ahead(vertices));
          detail::reserve_on_huge_pages(out.triangles, ahead(triangles));
        }
        merge::append_piece(out, piece, seam);
        if (options.slices_done) {
          // Every piece up to i has read what it reads; later pieces read from first_read(i + 1).
          const std::int64_t end = i + 1 < count ? first_read(i + 1) : nz;
          const auto [own_begin, own_end] = own_slices(i);
          const std::int64_t shared_end = own_begin < own_end ? own_begin : end;
          if (reported < shared_end) options.slices_done(reported, shared_end);
          reported = std::max(reported, end);
        }
        {
          const std::lock_guard lock(scratch_mutex);
          if (started < count) spent.push_back(std::move(piece.mesh));
        }
        total += piece.stats;
        if (extract.stats != nullptr) *extract.stats += piece.ambiguity;
      });
  if (count == 0 && options.slices_done && nz > 0) options.slices_done(0, nz);
  if (stats != nullptr) *stats = total;
  return out;
}

}  // namespace typemerge::core
