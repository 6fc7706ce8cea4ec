// merge_types: the merge procedure of type-merging-spec.md §4.1–4.5 on the indexed MC mesh.
//
// Recipe (merge_types at the bottom):
//   1. index the lattice: boundary-cube records (from the extractor, already in scan order)
//      get a row table so C + d is found by a binary search in one short row;
//   2. build vertex → triangle incidence as CSR (two passes over the triangles);
//   3. merge, cubes in scan order (z, y, x): pick a direction (D2, D3, FLAG of §4.1), then
//      collapse each moving pair of C + d (D1) with the checks of §4.5, and remove the
//      slivers the merge made (D6) — all in one transaction that is undone if any step fails;
//   4. a final sliver pass (finds none on every test surface; kept as a guard); 5. compact.
//
// Mesh state during merging: triangles keep their original vertex ids; a union-find `parent`
// maps an id to the vertex that absorbed it (a half-edge collapse a → b is parent[a] = b), and
// `next_member` links every class into a ring, so a vertex's current fan is the live
// triangles incident to any member and the original MC vertices it absorbed are the members.
// A second ring (`next_fan`) links only the members that still have live triangles, so a fan
// is gathered without visiting absorbed vertices. Each triangle's current corners (roots) are
// kept in `corner`, rewritten by each collapse for the triangles it moves and recomputed from
// the union-find for those a rollback moves back: fans are read without a find() per corner
// (abdomen −500 HU: merging 11 % faster). Classes are bounded (max_class_vertices),
// rings are spliced in O(1), and nothing is allocated per vertex or per collapse: fans and
// links live in fixed-size stack buffers (a larger fan is rejected, which only costs
// reduction).
#include "core/type_merging.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/cube_tables.h"
#include "core/parallel.h"
#include "core/self_intersections.h"

namespace typemerge::core {

namespace {

using P3 = std::array<double, 3>;

P3 sub(const P3& a, const P3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot3(const P3& a, const P3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
P3 cross3(const P3& a, const P3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

}  // namespace

namespace detail {

namespace {

double point_segment_distance_squared(const P3& p, const P3& a, const P3& b) {
  const P3 ab = sub(b, a);
  const P3 ap = sub(p, a);
  const double len2 = dot3(ab, ab);
  double t = len2 > 0.0 ? dot3(ap, ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const P3 q = {a[0] + t * ab[0] - p[0], a[1] + t * ab[1] - p[1], a[2] + t * ab[2] - p[2]};
  return dot3(q, q);
}

}  // namespace

double point_triangle_distance_squared(const P3& p, const P3& a, const P3& b, const P3& c) {
  const P3 ab = sub(b, a);
  const P3 ac = sub(c, a);
  const P3 n = cross3(ab, ac);
  const double n2 = dot3(n, n);
  const double scale = std::max({dot3(ab, ab), dot3(ac, ac), 1e-300});
  if (n2 <= 1e-24 * scale * scale) {
    // Degenerate: the triangle is (at most) its three edges.
    return std::min({point_segment_distance_squared(p, a, b),
                     point_segment_distance_squared(p, b, c),
                     point_segment_distance_squared(p, c, a)});
  }
  // Inside the prism over the triangle: distance to the plane; else to the nearest edge.
  const P3 ap = sub(p, a);
  const P3 bp = sub(p, b);
  const P3 cp = sub(p, c);
  const double wa = dot3(cross3(sub(c, b), bp), n);
  const double wb = dot3(cross3(sub(a, c), cp), n);
  const double wc = dot3(cross3(ab, ap), n);
  if (wa >= 0.0 && wb >= 0.0 && wc >= 0.0) {
    const double h = dot3(ap, n);
    return h * h / n2;
  }
  return std::min({point_segment_distance_squared(p, a, b),
                   point_segment_distance_squared(p, b, c),
                   point_segment_distance_squared(p, c, a)});
}

}  // namespace detail

namespace {

using VertexId = std::uint32_t;
using TriangleId = std::uint32_t;

constexpr VertexId kNoVertex = std::numeric_limits<VertexId>::max();
constexpr TriangleId kNoTriangle = std::numeric_limits<TriangleId>::max();
constexpr std::uint32_t kNoVersion = std::numeric_limits<std::uint32_t>::max();

// Largest fan (triangles around one vertex) and link the checks handle; MC fans have at most
// ~12 triangles, merged vertices a few times that.
constexpr int kMaxFan = 96;
static_assert(kMaxFan <= 255, "fan slots are stored in bytes");

// A triangle is a sliver when its height over the longest edge is below this fraction of that
// edge: collinear up to float rounding of positions that are exactly collinear in theory.
constexpr double kSliverRatio = 1e-5;

// Position of each cube edge's vertex in the cube's triangle list, slot = 3·triangle + corner,
// for the configurations that can merge (types 0–2: MC cases 1, 2, 5, 8, 9, never ambiguous,
// never with a centre vertex, so their triangulation is the single table entry). 0xFF = the
// edge is not cut. Derived from the case tables at compile time.
struct EdgeSlots {
  std::array<std::array<std::uint8_t, kCubeEdgeCount>, 256> slot{};
};

constexpr EdgeSlots build_edge_slots() {
  EdgeSlots table{};
  for (unsigned c = 0; c < 256; ++c) {
    for (auto& s : table.slot[c]) s = 0xFF;
    if (type_of(c).type == CubeType::kNone) continue;
    const CubeCase& cube_case = kConsistentCases.cases[kConsistentCases.first[c]];
    for (int t = cube_case.triangle_count - 1; t >= 0; --t) {
      for (int k = 0; k < 3; ++k) {
        table.slot[c][cube_case.triangles[t][k]] = static_cast<std::uint8_t>(3 * t + k);
      }
    }
  }
  return table;
}

constexpr EdgeSlots kEdgeSlots = build_edge_slots();

constexpr bool mergeable_cubes_are_plain() {
  for (unsigned c = 0; c < 256; ++c) {
    if (type_of(c).type == CubeType::kNone) continue;
    if (kCubeAmbiguousFaces[c] != 0) return false;  // D11: ambiguous cubes never merge
    if (kConsistentCases.cases[kConsistentCases.first[c]].centroid_count != 0) return false;
    for (int e = 0; e < kCubeEdgeCount; ++e) {
      const bool cut = ((kCubeCutEdges[c] >> e) & 1u) != 0;
      if (cut != (kEdgeSlots.slot[c][e] != 0xFF)) return false;
    }
  }
  return true;
}
static_assert(mergeable_cubes_are_plain());

// A small set of vertex ids in a fixed buffer (fans and links are short; linear search beats
// any hashing at these sizes). Buffers are left uninitialised on purpose: entries are written
// before they are read, and clearing a few hundred bytes per collapse is wasted work.
template <int N>
struct SmallSet {
  std::array<VertexId, N> items;
  int size = 0;
  bool overflow = false;

  bool contains(VertexId v) const {
    for (int i = 0; i < size; ++i) {
      if (items[i] == v) return true;
    }
    return false;
  }
  void insert(VertexId v) {
    if (contains(v)) return;
    if (size == N) {
      overflow = true;
      return;
    }
    items[size++] = v;
  }
};

// Fans hold a dozen triangles: insertion sort beats std::sort's dispatch at that size.
void insertion_sort(VertexId* items, int n) {
  for (int i = 1; i < n; ++i) {
    const VertexId v = items[i];
    int j = i;
    for (; j > 0 && items[j - 1] > v; --j) items[j] = items[j - 1];
    items[j] = v;
  }
}

struct Fan {
  std::array<TriangleId, kMaxFan> triangles;
  int size = 0;
  bool overflow = false;
};

// The merge state of one vertex (see "Mesh state" above).
struct VertexState {
  VertexId parent = 0;       // union-find: the vertex that absorbed this one
  VertexId next_member = 0;  // ring through each class
  VertexId next_fan = 0;     // ring through the members with live triangles
  std::uint32_t class_size = 1;  // members of the class, valid at its root
  std::uint32_t offset = 0;      // CSR: first incident triangle
  std::uint32_t live_end = 0;    // end of the still-live prefix of the incident triangles
  TriangleId witness = kNoTriangle;  // hint: the triangle that last kept the vertex near
  std::uint32_t witness_version = kNoVersion;  // version of the witness when it was found
};
static_assert(sizeof(VertexState) == 32);

// The merge state of one triangle.
struct TriangleState {
  std::array<VertexId, 3> corner;  // its current corners (roots)
  std::uint32_t version : 31;      // changes of shape so far
  std::uint32_t alive : 1;
};
static_assert(sizeof(TriangleState) == 16);

// A vertex's neighbours, sorted by id (closed_link), so that two links meet in one merge pass.
struct Link {
  std::array<VertexId, kMaxFan> items;
  int size = 0;
};

// Cheap filters before merge_type3's lattice look-ups, per plane of kType3Planes: which
// indices a block's first cube can have, and which pairs its first two (built once, on first
// use, from type3_blocks()).
struct Type3Filter {
  std::array<bool, 256> first{};
  std::vector<bool> pair = std::vector<bool>(1u << 16);
};

const std::array<Type3Filter, 3>& type3_filters() {
  static const std::array<Type3Filter, 3> filters = [] {
    std::array<Type3Filter, 3> built;
    for (std::size_t plane = 0; plane < built.size(); ++plane) {
      for (const Type3Block& block : type3_blocks()[plane]) {
        built[plane].first[block.key & 0xFFu] = true;
        built[plane].pair[block.key & 0xFFFFu] = true;
      }
    }
    return built;
  }();
  return filters;
}

class Merger {
 public:
  // `frozen` (empty, or one flag per vertex): vertices that neither move nor absorb another
  // (the crossing guard's, see merge_and_compact).
  Merger(const TriangleMesh& mesh, std::span<const BoundaryCube> cubes,
         const MergeOptions& options, MergeStats& stats,
         std::span<const std::uint8_t> frozen = {})
      : mesh_(mesh), cubes_(cubes), options_(options), stats_(stats), frozen_(frozen) {
    const double deg = std::numbers::pi / 180.0;
    cos_normal_change_ = std::cos(options.max_normal_change_deg * deg);
    cos_normal_gradient_ = std::cos(options.max_normal_to_gradient_deg * deg);
    epsilon2_ = options.epsilon_voxels * options.epsilon_voxels;
    fan_slot_.assign(mesh.triangles.size(), 0);
  }

  // Builds the incidence lists and the lattice rows.
  void build() {
    build_incidence();
    build_rows();
  }

  // Compacted output: surviving vertices in original order, live triangles in original order.
  // `new_id` (optional) receives each input vertex's id in the output (kNoVertex: dropped);
  // `changed` (optional) flags each output triangle that is not an MC triangle as it was.
  TriangleMesh result(std::vector<VertexId>* id_map = nullptr,
                      std::vector<std::uint8_t>* changed = nullptr) {
    TriangleMesh out;
    const std::size_t n = mesh_.positions.size();
    std::vector<VertexId> local_ids;
    std::vector<VertexId>& new_id = id_map != nullptr ? *id_map : local_ids;
    new_id.assign(n, kNoVertex);
    std::size_t triangles = 0;
    for (TriangleId t = 0; t < triangle_.size(); ++t) {
      if (triangle_[t].alive == 0) continue;
      ++triangles;
      for (VertexId v : current(t)) new_id[v] = 0;
    }
    // Exact sizes: the output is held (extract_type_merged keeps every piece until the end).
    const auto vertices = static_cast<std::size_t>(
        std::count(new_id.begin(), new_id.end(), VertexId{0}));
    out.positions.reserve(vertices);
    out.normals.reserve(vertices);
    out.triangles.reserve(triangles);
    VertexId next = 0;
    for (std::size_t v = 0; v < n; ++v) {
      if (new_id[v] == kNoVertex) continue;
      new_id[v] = next++;
      out.positions.push_back(mesh_.positions[v]);
      out.normals.push_back(mesh_.normals[v]);
    }
    if (changed != nullptr) changed->clear();
    for (TriangleId t = 0; t < triangle_.size(); ++t) {
      if (triangle_[t].alive == 0) continue;
      const auto c = current(t);
      out.triangles.push_back({new_id[c[0]], new_id[c[1]], new_id[c[2]]});
      if (changed != nullptr) changed->push_back(c != mesh_.triangles[t] ? 1 : 0);
    }
    return out;
  }

  // The class (root) an input vertex belongs to after merging.
  VertexId class_of(VertexId v) { return find(v); }

  // ---- Mesh state ------------------------------------------------------------------------

  void build_incidence() {
    const std::size_t n = mesh_.positions.size();
    const std::size_t m = mesh_.triangles.size();
    vertex_.assign(n, VertexState{});
    triangle_.resize(m);
    for (TriangleId t = 0; t < m; ++t) triangle_[t] = {mesh_.triangles[t], 0, 1};
    for (VertexId v = 0; v < n; ++v) {
      VertexState& s = vertex_[v];
      s.parent = s.next_member = s.next_fan = v;
    }
    // CSR: count, prefix sum, fill (flying-edges style exact allocation); `live_end` is the
    // fill cursor, which ends at the end of each list.
    for (const auto& tri : mesh_.triangles) {
      for (VertexId v : tri) ++vertex_[v].live_end;
    }
    std::uint32_t total = 0;
    for (VertexState& s : vertex_) {
      s.offset = total;
      total += std::exchange(s.live_end, total);
    }
    incident_.resize(total);
    for (TriangleId t = 0; t < m; ++t) {
      for (VertexId v : mesh_.triangles[t]) incident_[vertex_[v].live_end++] = t;
    }
  }

  // Removes a triangle whose death is final (committed, or outside a transaction) from the
  // incidence lists of its three vertices, keeping the order of the others: a class that has
  // absorbed many vertices then walks only its live triangles, in the same order as before.
  void drop_dead(TriangleId t) {
    for (VertexId v : mesh_.triangles[t]) {
      std::uint32_t* first = incident_.data() + vertex_[v].offset;
      std::uint32_t* last = incident_.data() + vertex_[v].live_end;
      std::uint32_t* it = std::remove(first, last, t);
      vertex_[v].live_end = static_cast<std::uint32_t>(it - incident_.data());
    }
  }
  // drop_dead, then takes each corner whose incidence list is now empty out of its class's fan
  // ring (next_fan), so gather_fan walks only members that still have live triangles. Only
  // for final deaths (drop_dead's condition) and never for a root (its ring is spliced by
  // later collapses and their rollbacks); a non-root member is out of any open transaction.
  void retire(TriangleId t) {
    drop_dead(t);
    for (VertexId v : mesh_.triangles[t]) {
      if (vertex_[v].live_end != vertex_[v].offset || vertex_[v].next_fan == kNoVertex) continue;
      const VertexId r = find(v);
      if (r == v) continue;
      VertexId p = r;
      while (vertex_[p].next_fan != v) p = vertex_[p].next_fan;
      vertex_[p].next_fan = vertex_[v].next_fan;
      vertex_[v].next_fan = kNoVertex;
    }
  }


  // Path compression only outside a merge transaction: a rollback resets parent[a] = a, which
  // would strand members that compression had pointed past a.
  VertexId find(VertexId v) {
    VertexId root = v;
    while (vertex_[root].parent != root) root = vertex_[root].parent;
    if (!in_transaction_) {
      while (vertex_[v].parent != root) v = std::exchange(vertex_[v].parent, root);
    }
    return root;
  }

  // A triangle's corners as the collapses so far made them (kept in `corner`, which every
  // collapse and rollback updates for the triangles it moves).
  const std::array<VertexId, 3>& current(TriangleId t) const { return triangle_[t].corner; }

  // The same from the union-find: what `corner` is reset to when a collapse is undone.
  std::array<VertexId, 3> resolve(TriangleId t) {
    const auto& tri = mesh_.triangles[t];
    return {find(tri[0]), find(tri[1]), find(tri[2])};
  }

  P3 position(VertexId v) const {
    const auto& p = mesh_.positions[v];
    return {p[0], p[1], p[2]};
  }
  P3 normal(VertexId v) const {
    const auto& p = mesh_.normals[v];
    return {p[0], p[1], p[2]};
  }

  // Live triangles around representative r: those incident to any member of its class (each
  // appears once: a live triangle has one vertex per class).
  void gather_fan(VertexId r, Fan& fan) const {
    fan.size = 0;
    fan.overflow = false;
    VertexId m = r;
    do {
      for (std::uint32_t i = vertex_[m].offset; i < vertex_[m].live_end; ++i) {
        const TriangleId t = incident_[i];
        if (triangle_[t].alive == 0) continue;
        if (fan.size == kMaxFan) {
          fan.overflow = true;
          return;
        }
        fan.triangles[fan.size++] = t;
      }
      m = vertex_[m].next_fan;
    } while (m != r);
  }

  // ---- The checked half-edge collapse (spec §4.5 tryCollapse) -----------------------------

  static bool is_sliver(const P3& p0, const P3& p1, const P3& p2, P3* n) {
    const P3 e0 = sub(p1, p0);
    const P3 e1 = sub(p2, p0);
    const P3 e2 = sub(p2, p1);
    *n = cross3(e0, e1);
    const double longest2 = std::max({dot3(e0, e0), dot3(e1, e1), dot3(e2, e2)});
    // |n| = 2·area = height·longest; sliver when height <= kSliverRatio·longest.
    return dot3(*n, *n) <= kSliverRatio * kSliverRatio * longest2 * longest2;
  }

  // A fan as it will be after a → b, its triangles' corners and plane normals computed once
  // and only when first needed (a class of k members tests up to k × fan-size triangles; the
  // geometry is the same for every member). The values are computed by the same expressions
  // as a direct test, so the answers are bit for bit those of the direct test.
  struct MovedFan {
    const Fan* fan = nullptr;
    VertexId a = kNoVertex;
    VertexId b = kNoVertex;
    // 0 = not yet looked at, 1 = dies, 2 = lives (ids and `changed` known), 3 = geometry too.
    std::array<std::uint8_t, kMaxFan> state;
    std::array<std::uint8_t, kMaxFan> changed;  // 1 = has a as a corner: its shape changes
    std::array<std::array<VertexId, 3>, kMaxFan> ids;  // corners after a → b
    std::array<std::array<P3, 3>, kMaxFan> corners;
    std::array<P3, kMaxFan> normal;  // (c1 − c0) × (c2 − c0), as within_epsilon computes it
    std::array<double, kMaxFan> normal2;

    MovedFan(const Fan& f, VertexId from, VertexId to) : fan(&f), a(from), b(to) {
      std::fill_n(state.begin(), f.size, std::uint8_t{0});
    }
  };

  // Whether fan triangle i survives a → b and whether its shape changes, found once. The
  // geometry is a second step (prepare_geometry): a current witness needs only this one.
  void prepare(MovedFan& moved, int i) {
    if (moved.state[i] != 0) return;
    auto c = current(moved.fan->triangles[i]);
    bool has_a = false;
    bool has_b = false;
    for (VertexId& v : c) {
      has_a = has_a || v == moved.a;
      has_b = has_b || v == moved.b;
      if (v == moved.a) v = moved.b;
    }
    moved.changed[i] = has_a ? 1 : 0;
    if (has_a && has_b) {
      moved.state[i] = 1;
      return;
    }
    moved.state[i] = 2;
    moved.ids[i] = c;
  }

  // prepare, then the moved corners and plane normal of a surviving fan triangle i.
  void prepare_geometry(MovedFan& moved, int i) {
    prepare(moved, i);
    if (moved.state[i] != 2) return;
    moved.state[i] = 3;
    auto& q = moved.corners[i];
    for (int k = 0; k < 3; ++k) q[k] = position(moved.ids[i][k]);
    moved.normal[i] = cross3(sub(q[1], q[0]), sub(q[2], q[0]));
    moved.normal2[i] = dot3(moved.normal[i], moved.normal[i]);
  }

  bool moved_triangle_near(MovedFan& moved, int i, const P3& p) {
    prepare_geometry(moved, i);
    if (moved.state[i] == 1) return false;
    // Distance test with a cheap exit: the distance to the triangle is at least the distance
    // to its plane (most candidate triangles are rejected by that alone).
    const auto& q = moved.corners[i];
    const double n2 = moved.normal2[i];
    const double h = dot3(sub(p, q[0]), moved.normal[i]);
    if (h * h > epsilon2_ * n2 && n2 > 0.0) return false;
    return detail::point_triangle_distance_squared(p, q[0], q[1], q[2]) <= epsilon2_;
  }

  // Would every member of class r (the MC vertices it absorbed) stay within epsilon of the
  // fan of r after a → b (`moved`)? Each vertex remembers the triangle that last kept it within
  // epsilon (`witness`) with that triangle's shape version (`witness_version`: `version` counts
  // the changes of shape of a triangle, i.e. collapses and rollbacks at its corners). A witness
  // that is current, in the fan and not moved by a → b still has the shape it was found near,
  // so the member is near without a test (most members of a large class); otherwise it is
  // tried first. Only the work changes, not the outcome: a test of such a witness would repeat
  // the one that recorded it.
  bool class_within_epsilon(VertexId r, MovedFan& moved) {
    const Fan& fan = *moved.fan;
    // Where each fan triangle sits in the fan, for an O(1) witness lookup (stale entries of
    // other fans are caught by the check below).
    for (int i = 0; i < fan.size; ++i) fan_slot_[fan.triangles[i]] = static_cast<std::uint8_t>(i);
    VertexId m = r;
    do {
      // r itself is a corner of every triangle of its fan, unless r is a, which moves.
      if (m != r || r == moved.a) {
        int first = -1;
        const TriangleId w = vertex_[m].witness;
        if (w != kNoTriangle) {
          const int slot = fan_slot_[w];
          if (slot < fan.size && fan.triangles[slot] == w) first = slot;
        }
        bool near = false;
        if (first >= 0) {
          prepare(moved, first);
          if (moved.state[first] >= 2 && moved.changed[first] == 0 &&
              vertex_[m].witness_version == triangle_[w].version) {
            near = true;
          } else {
            const P3 p = position(m);
            near = moved_triangle_near(moved, first, p);
            if (near) record_witness(m, moved.changed[first] != 0);
          }
        }
        if (!near) {
          const P3 p = position(m);
          for (int i = 0; i < fan.size && !near; ++i) {
            if (i == first) continue;
            if (moved_triangle_near(moved, i, p)) {
              near = true;
              vertex_[m].witness = fan.triangles[i];
              record_witness(m, moved.changed[i] != 0);
            }
          }
        }
        if (!near) return false;
      }
      m = vertex_[m].next_member;
    } while (m != r);
    return true;
  }

  // class_within_epsilon(x, …) for a neighbour x of a, without gathering x's fan, in the
  // common case where it needs no distance test: every member other than x has a witness of
  // the current shape, live, in x's fan (a corner in x's class) and without a as a corner, so
  // that test passes each member at its first step. False: ask class_within_epsilon.
  bool witnesses_hold(VertexId x, VertexId a) {
    for (VertexId m = vertex_[x].next_member; m != x; m = vertex_[m].next_member) {
      const TriangleId w = vertex_[m].witness;
      if (w == kNoTriangle || triangle_[w].alive == 0 ||
          vertex_[m].witness_version != triangle_[w].version) {
        return false;
      }
      const auto& c = current(w);
      if (c[0] == a || c[1] == a || c[2] == a) return false;
      if (c[0] != x && c[1] != x && c[2] != x) return false;
    }
    return true;
  }

  // A witness found on a triangle that the collapse under test moves holds for the shape after
  // the collapse: it becomes current only if the collapse is applied.
  void record_witness(VertexId m, bool on_moved_triangle) {
    if (on_moved_triangle) {
      vertex_[m].witness_version = kNoVersion;
      pending_witness_.push_back(m);
    } else {
      vertex_[m].witness_version = triangle_[vertex_[m].witness].version;
    }
  }

  // The link of vertex r (its neighbours, sorted by id) from its fan's current corners; false
  // when the fan is not closed. In a closed fan every neighbour follows r once and precedes
  // it once, so the followers and the predecessors are the same multiset; a neighbour seen
  // only one way marks a boundary edge. The sorted followers, duplicates dropped, are then the
  // link (sorted arrays: no set insertion, whose branchy linear searches cost more than the
  // sorts on fans of a dozen triangles).
  bool closed_link(VertexId r, const Fan& fan, Link& link) const {
    std::array<VertexId, kMaxFan> prev;
    VertexId* next = link.items.data();
    const int n = fan.size;
    for (int i = 0; i < n; ++i) {
      const auto& c = current(fan.triangles[i]);
      const int k = c[0] == r ? 0 : c[1] == r ? 1 : 2;
      next[i] = c[(k + 1) % 3];
      prev[i] = c[(k + 2) % 3];
    }
    insertion_sort(next, n);
    insertion_sort(prev.data(), n);
    for (int i = 0; i < n; ++i) {
      if (next[i] != prev[i]) return false;
    }
    link.size = static_cast<int>(std::unique(next, next + n) - next);
    return true;
  }

  // A vertex's fan and its link.
  struct Star {
    Fan fan;
    Link link;
  };

  // The star of r; false (the rejection counted) when its fan is too large or not closed.
  bool gather_star(VertexId r, Star& star) {
    gather_fan(r, star.fan);
    if (star.fan.overflow) return reject(stats_.rejected_fan_size);
    if (!closed_link(r, star.fan, star.link)) return reject(stats_.rejected_boundary);
    return true;
  }

  bool try_collapse(VertexId a_in, VertexId b_in) {
    const VertexId a = find(a_in);
    const VertexId b = find(b_in);
    if (a == b) return true;
    ++stats_.collapses_tried;
    pending_witness_.clear();
    // Frozen vertices are never merged, so each is its own root.
    if (!frozen_.empty() && (frozen_[a] != 0 || frozen_[b] != 0)) {
      return reject(stats_.rejected_frozen);
    }
    if (options_.max_class_vertices != 0 &&
        vertex_[a].class_size + vertex_[b].class_size > options_.max_class_vertices) {
      return reject(stats_.rejected_class_size);
    }

    Star star_a;
    if (!gather_star(a, star_a)) return false;
    const Fan& fan_a = star_a.fan;
    const Link& link_a = star_a.link;

    // The edge (a, b).
    SmallSet<4> opposite;
    int edge_ab = 0;
    for (int i = 0; i < fan_a.size; ++i) {
      const auto& c = current(fan_a.triangles[i]);
      const int k = c[0] == a ? 0 : c[1] == a ? 1 : 2;
      const VertexId next = c[(k + 1) % 3];
      const VertexId prev = c[(k + 2) % 3];
      if (next == b || prev == b) {
        ++edge_ab;
        opposite.insert(next == b ? prev : next);
      }
    }
    if (edge_ab != 2 || opposite.size != 2) return reject(stats_.rejected_link);

    // Fold-over: every triangle of a that survives keeps its orientation within the limits.
    // Tested before b's fan is gathered: it rejects most (abdomen bone: 63 k of 88 k
    // rejections), and every test up to the distance test is free of side effects, so the
    // order changes which counter a rejection goes to, never the outcome.
    const P3 pb = position(b);
    for (int i = 0; i < fan_a.size; ++i) {
      const auto& c = current(fan_a.triangles[i]);
      if (c[0] == b || c[1] == b || c[2] == b) continue;
      P3 q[3];
      P3 ref{0, 0, 0};
      for (int k = 0; k < 3; ++k) {
        q[k] = c[k] == a ? pb : position(c[k]);
        const P3 nk = normal(c[k] == a ? b : c[k]);
        for (int x = 0; x < 3; ++x) ref[x] += nk[x];
      }
      P3 n0;
      P3 n1;
      const bool sliver0 = is_sliver(position(c[0]), position(c[1]), position(c[2]), &n0);
      const bool sliver1 = is_sliver(q[0], q[1], q[2], &n1);
      // Slivers (collinear vertices, typical on flat data) have no reliable normal: they are
      // allowed here and removed by the clean-up; rotations and flips of real triangles are not.
      if (!sliver0 && !sliver1 &&
          dot3(n0, n1) < cos_normal_change_ * std::sqrt(dot3(n0, n0) * dot3(n1, n1))) {
        return reject(stats_.rejected_normal);
      }
      const double ref2 = dot3(ref, ref);
      if (!sliver1 && ref2 > 0.0 &&
          dot3(n1, ref) < cos_normal_gradient_ * std::sqrt(dot3(n1, n1) * ref2)) {
        return reject(stats_.rejected_gradient);
      }
    }

    // Nor does a boundary vertex absorb one: a piece's seam (extract_type_merged) must stay as
    // the piece beside it has it, and what is beyond a boundary cannot be judged from here.
    Star star_b;
    if (!gather_star(b, star_b)) return false;
    const Fan& fan_b = star_b.fan;
    const Link& link_b = star_b.link;
    // Link condition: the common neighbours of a and b are exactly the two opposite vertices;
    // and not the last edge of a tetrahedron (both of valence 3), which would leave a pillow.
    int common = 0;
    for (int i = 0, j = 0; i < link_a.size && j < link_b.size;) {
      const VertexId v = link_a.items[i];
      const VertexId w = link_b.items[j];
      if (v != w) {
        (v < w ? i : j) += 1;
        continue;
      }
      ++i;
      ++j;
      if (v == b) continue;
      if (!opposite.contains(v)) return reject(stats_.rejected_link);
      ++common;
    }
    if (common != 2) return reject(stats_.rejected_link);
    if (link_a.size == 3 && link_b.size == 3) return reject(stats_.rejected_link);

    // Distance (D7): the MC vertices absorbed by a and by b against the new fan of b (a's
    // fan mapped to b plus b's fan), and those absorbed by a's other neighbours, whose fans
    // change shape too, against their new fans.
    Fan fan_ab;
    for (int i = 0; i < fan_a.size; ++i) fan_ab.triangles[fan_ab.size++] = fan_a.triangles[i];
    for (int i = 0; i < fan_b.size; ++i) {
      const auto& c = current(fan_b.triangles[i]);
      if (c[0] == a || c[1] == a || c[2] == a) continue;
      if (fan_ab.size == kMaxFan) return reject(stats_.rejected_fan_size);
      fan_ab.triangles[fan_ab.size++] = fan_b.triangles[i];
    }
    MovedFan moved_ab(fan_ab, a, b);
    if (!class_within_epsilon(a, moved_ab) || !class_within_epsilon(b, moved_ab)) {
      return reject(stats_.rejected_distance);
    }
    for (int j = 0; j < link_a.size; ++j) {
      const VertexId x = link_a.items[j];
      if (x == b || vertex_[x].next_member == x) continue;  // a lone vertex lies on its own fan
      if (witnesses_hold(x, a)) continue;
      Fan fan_x;
      gather_fan(x, fan_x);
      if (fan_x.overflow) return reject(stats_.rejected_fan_size);
      MovedFan moved_x(fan_x, a, b);
      if (!class_within_epsilon(x, moved_x)) return reject(stats_.rejected_distance);
    }

    // Apply: a joins b's class; the two triangles on the edge (a, b) die.
    JournalEntry entry{a, b, {0, 0}, 0};
    vertex_[a].parent = b;
    std::swap(vertex_[a].next_member, vertex_[b].next_member);
    std::swap(vertex_[a].next_fan, vertex_[b].next_fan);
    vertex_[b].class_size += vertex_[a].class_size;
    for (int i = 0; i < fan_a.size; ++i) {
      ++triangle_[fan_a.triangles[i]].version;  // a's triangles change shape
      // The corners as they are now that a is b.
      std::array<VertexId, 3> c = current(fan_a.triangles[i]);
      for (VertexId& v : c) v = v == a ? b : v;
      triangle_[fan_a.triangles[i]].corner = c;
      if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) {
        triangle_[fan_a.triangles[i]].alive = 0;
        if (entry.killed_count < 2) entry.killed[entry.killed_count++] = fan_a.triangles[i];
      }
    }
    assert(entry.killed_count == 2);
    for (VertexId m : pending_witness_) record_witness(m, false);  // now the current shape
    if (in_transaction_) {
      journal_.push_back(entry);
    } else {
      for (int k = 0; k < entry.killed_count; ++k) retire(entry.killed[k]);
    }
    ++stats_.collapses_done;
    return true;
  }

  // ---- Merge transactions ------------------------------------------------------------------
  //
  // A merge may leave slivers (collinear vertices on flat data) whose normals the fold-over
  // test cannot judge. They are removed at once by exact collapses; when that is impossible
  // (e.g. the middle vertex is on a mesh boundary) the whole merge is undone. Undo is cheap
  // because a collapse changes three things: parent[a], the ring splice, two alive flags.

  struct JournalEntry {
    VertexId a;
    VertexId b;
    std::array<TriangleId, 2> killed;
    int killed_count;
  };

  void begin_transaction() {
    in_transaction_ = true;
    journal_.clear();
    slivers_at_begin_ = stats_.sliver_collapses;
  }

  // Every merge runs in a transaction, where find() may not compress paths; so the classes
  // the merge touched are flattened here (each member points at its root), which keeps every
  // later find() at one or two steps on surfaces where classes chain over many merges.
  void commit() {
    in_transaction_ = false;
    for (const JournalEntry& entry : journal_) {
      for (int k = 0; k < entry.killed_count; ++k) retire(entry.killed[k]);
      const VertexId root = find(entry.b);
      if (vertex_[entry.a].parent == root) continue;  // flattened already
      VertexId m = root;
      do {
        vertex_[m].parent = root;
        m = vertex_[m].next_member;
      } while (m != root);
    }
  }

  void rollback() {
    for (auto it = journal_.rbegin(); it != journal_.rend(); ++it) {
      for (int k = 0; k < it->killed_count; ++k) triangle_[it->killed[k]].alive = 1;
      std::swap(vertex_[it->a].next_member, vertex_[it->b].next_member);
      std::swap(vertex_[it->a].next_fan, vertex_[it->b].next_fan);
      vertex_[it->a].parent = it->a;
      vertex_[it->b].class_size -= vertex_[it->a].class_size;
      // a's triangles take back their old shape: a new version, so that witnesses found on
      // the undone shape are not trusted.
      Fan fan_a;
      gather_fan(it->a, fan_a);
      for (int i = 0; i < fan_a.size; ++i) {
        ++triangle_[fan_a.triangles[i]].version;
        triangle_[fan_a.triangles[i]].corner = resolve(fan_a.triangles[i]);
      }
    }
    stats_.collapses_done -= journal_.size();
    stats_.sliver_collapses = slivers_at_begin_;
    journal_.clear();
    in_transaction_ = false;
  }

  // Removes the slivers in the fans of the vertices in `touched` (the targets of the merge's
  // collapses: only their fans changed shape); false when one cannot be removed.
  bool clean_touched_slivers(SmallSet<16>& touched) {
    constexpr int kRounds = 4;
    for (int round = 0; round < kRounds; ++round) {
      bool found = false;
      bool changed = false;
      for (int i = 0; i < touched.size; ++i) {
        const VertexId r = find(touched.items[i]);
        Fan fan;
        gather_fan(r, fan);
        if (fan.overflow) return false;
        for (int k = 0; k < fan.size; ++k) {
          const TriangleId t = fan.triangles[k];
          if (triangle_[t].alive == 0) continue;
          const auto c = current(t);
          P3 n;
          if (!is_sliver(position(c[0]), position(c[1]), position(c[2]), &n)) continue;
          found = true;
          VertexId end = kNoVertex;
          if (collapse_sliver(t, &end)) {
            changed = true;
            touched.insert(end);
          }
        }
      }
      if (touched.overflow) return false;
      if (!found) return true;
      if (!changed) return false;
    }
    return false;
  }

  bool reject(std::size_t& counter) {
    ++counter;
    return false;
  }

  // ---- Lattice --------------------------------------------------------------------------

  // Rows of cube records: records are in scan order, so each (y, z) row is a contiguous,
  // x-sorted range; row_start_ holds the ranges (4 bytes per row instead of a hash map or a
  // dense cube grid).
  void build_rows() {
    if (cubes_.empty()) return;
    std::int32_t y_max = cubes_[0].y;
    y_min_ = cubes_[0].y;
    z_min_ = cubes_.front().z;
    const std::int32_t z_max = cubes_.back().z;
    for (const BoundaryCube& c : cubes_) {
      y_min_ = std::min(y_min_, c.y);
      y_max = std::max(y_max, c.y);
    }
    row_length_ = static_cast<std::int64_t>(y_max) - y_min_ + 1;
    const std::int64_t rows = row_length_ * (static_cast<std::int64_t>(z_max) - z_min_ + 1);
    z_rows_ = static_cast<std::int64_t>(z_max) - z_min_ + 1;
    row_start_.assign(static_cast<std::size_t>(rows + 1), 0);
    for (const BoundaryCube& c : cubes_) {
      ++row_start_[static_cast<std::size_t>(row_of(c.y, c.z) + 1)];
    }
    for (std::size_t r = 0; r + 1 < row_start_.size(); ++r) row_start_[r + 1] += row_start_[r];
    flag_.assign(cubes_.size(), kNoMergeDirection);
    run_.assign(cubes_.size(), 1);
    started_.assign(cubes_.size(), 0);
  }

  std::int64_t row_of(std::int32_t y, std::int32_t z) const {
    return (static_cast<std::int64_t>(z) - z_min_) * row_length_ + (y - y_min_);
  }

  // Record index of boundary cube (x, y, z), or −1 when that cube has no surface.
  std::int64_t find_cube(std::int32_t x, std::int32_t y, std::int32_t z) const {
    if (y < y_min_ || y - y_min_ >= row_length_ || z < z_min_ || z - z_min_ >= z_rows_) return -1;
    const std::size_t row = static_cast<std::size_t>(row_of(y, z));
    // Branch-free lower bound (the look-ups of merge_cube and merge_type3 land anywhere in a
    // row, so std::lower_bound's branches were mispredicted about half the time).
    std::size_t base = row_start_[row];
    std::size_t count = row_start_[row + 1] - base;
    if (count == 0) return -1;
    while (count > 1) {
      const std::size_t half = count / 2;
      base = cubes_[base + half - 1].x < x ? base + half : base;
      count -= half;
    }
    if (cubes_[base].x != x) return -1;
    return static_cast<std::int64_t>(base);
  }

  // Record index of the cube at record's cube + offset, or −1. Along +x by t the record t
  // places on holds it when the cubes between have a surface too (records are in scan order),
  // which is the common case of a run; otherwise the row is searched.
  std::int64_t neighbour_cube(std::size_t record, const std::array<int, 3>& offset) const {
    const BoundaryCube& c = cubes_[record];
    if (offset[0] > 0 && offset[1] == 0 && offset[2] == 0) {
      const std::size_t ahead = record + static_cast<std::size_t>(offset[0]);
      if (ahead < cubes_.size()) {
        const BoundaryCube& n = cubes_[ahead];
        if (n.x == c.x + offset[0] && n.y == c.y && n.z == c.z) {
          return static_cast<std::int64_t>(ahead);
        }
      }
      if (offset[0] == 1) return -1;  // the next cube of the row would be the next record
    }
    return find_cube(c.x + offset[0], c.y + offset[1], c.z + offset[2]);
  }

  std::int64_t step(std::size_t record, int d, int times = 1) const {
    const auto& u = kMergeDirectionVector[d];
    return neighbour_cube(record, {times * u[0], times * u[1], times * u[2]});
  }

  VertexId edge_vertex(std::size_t record, int edge) const {
    const BoundaryCube& c = cubes_[record];
    const unsigned slot = kEdgeSlots.slot[c.index][edge];
    assert(slot != 0xFF);
    return mesh_.triangles[c.first_triangle + slot / 3][slot % 3];
  }

  // ---- Merging (spec §4.1 with §4.4 decisions) ----------------------------------------------

  // Every cube record in scan order.
  void merge_all() {
    for (std::size_t r = 0; r < cubes_.size(); ++r) merge_cube(r);
  }

  // Spec §4.1 for one cube.
  void merge_cube(std::size_t r) {
    const unsigned index = cubes_[r].index;
    const TypeEntry& entry = type_of(index);
    if (entry.type == CubeType::kNone) return;  // type 4 and every ambiguous cube (D11)
    unsigned candidates = entry.merge;
    if (entry.type == CubeType::kHexagon && options_.hexagon_all_lines) candidates = entry.lines;
    // FLAG (§4.1): a cube absorbed along d may only continue the run along d.
    if (flag_[r] != kNoMergeDirection) candidates &= 1u << flag_[r];

    // D2 + D3: the direction with the longest look-ahead run of the same raw index whose
    // next cube is not yet absorbed; ties go to the table order (primary first). In scan
    // order the next cube has not started a run of its own yet.
    int best = -1;
    int best_length = 0;
    for (int d = 0; d < kMergeDirectionCount; ++d) {
      if (((candidates >> d) & 1u) == 0) continue;
      const std::int64_t next = step(r, d);
      if (next < 0) continue;
      const std::size_t n = static_cast<std::size_t>(next);
      if (cubes_[n].index != index || flag_[n] != kNoMergeDirection || started_[n] != 0) {
        continue;
      }
      int length = 1;
      while (length < options_.run_cap) {
        const std::int64_t further = step(r, d, length + 1);
        if (further < 0 || cubes_[static_cast<std::size_t>(further)].index != index) break;
        ++length;
      }
      if (length > best_length) {
        best = d;
        best_length = length;
      }
    }
    if (best < 0) return;
    if (run_[r] >= options_.run_cap) {  // D9
      ++stats_.runs_capped;
      return;
    }

    // D1: the vertices of C + d on the rear edges move onto its front edges.
    const std::size_t next = static_cast<std::size_t>(step(r, best));
    const unsigned cut = kCubeCutEdges[index];
    const MoveRow& row = kMoveTable[best];
    bool ok = true;
    SmallSet<16> touched;
    begin_transaction();
    for (int m = 0; m < row.move_count && ok; ++m) {
      const int s = row.moves[m].source;
      const int t = row.moves[m].target;
      if (((cut >> s) & 1u) == 0 || ((cut >> t) & 1u) == 0) continue;
      ok = try_collapse(edge_vertex(next, s), edge_vertex(next, t));
      touched.insert(edge_vertex(next, t));
    }
    bool slivers_ok = true;
    if (ok) {
      slivers_ok = clean_touched_slivers(touched);
      ok = slivers_ok;
    }
    if (!ok) {
      // All or nothing: a partly merged cube would break the run structure FLAG assumes.
      rollback();
      if (!slivers_ok) ++stats_.rejected_sliver;
      ++stats_.merges_abandoned;
      return;
    }
    commit();
    flag_[next] = static_cast<std::uint8_t>(best);
    run_[next] = static_cast<std::uint8_t>(std::min(run_[r] + 1, 255));
    started_[r] = 1;
    ++stats_.cubes_merged_by_type[static_cast<std::size_t>(paper_type(entry.type))];
    if (entry.type == CubeType::kHexagon) ++stats_.hexagon_merges;
    if (entry.type == CubeType::kMinor) ++stats_.minor_merges;
    ++stats_.merges_by_direction[static_cast<std::size_t>(best)];
  }

  // ---- Type 3 (spec §3.4, D10) ----------------------------------------------------------------

  // Every block of four cubes in a lattice plane that one plane creates with corner cubes on
  // a diagonal (type3_blocks; the slice first, then xz and yz), in scan order of its first
  // cube: the surface vertex on the block's centre edge, if no earlier collapse absorbed it,
  // is collapsed onto one of the corner cubes' two other vertices (its neighbours on the bold
  // diagonal; the first that passes the checks of §4.5), with the sliver clean-up, in one
  // transaction. After the type 0–2 pass, as the spec asks ("optional and last"). Blocks are
  // found by their cubes' MC indices, so a block some type 0–2 merge went through is tried too
  // (the checks judge the surface as it is now): on the abdomen's bone (slice blocks, centre
  // vertices only) that removes 3.7 times the triangles that untouched blocks alone give.
  void merge_type3() {
    for (std::size_t plane = 0; plane < kType3Planes.size(); ++plane) {
      const std::vector<Type3Block>& blocks = type3_blocks()[plane];
      const Type3Plane& axes = kType3Planes[plane];
      const std::array<bool, 256>& possible_first = type3_filters()[plane].first;
      const std::vector<bool>& possible_pair = type3_filters()[plane].pair;
      const std::array<std::array<int, 3>, 3> offsets = {axes.h, axes.v, axes.diagonal()};
      const std::array<int, 4> centre_edges = type3_centre_edges(axes);
      for (std::size_t r = 0; r < cubes_.size(); ++r) {
        if (!possible_first[cubes_[r].index]) continue;
        std::array<std::size_t, 4> block{r, 0, 0, 0};
        bool complete = true;
        for (int k = 0; k < 3 && complete; ++k) {
          const std::int64_t c = neighbour_cube(r, offsets[k]);
          complete = c >= 0;
          block[k + 1] = static_cast<std::size_t>(c);
          if (complete && k == 0) {
            complete = possible_pair[cubes_[r].index | cubes_[block[1]].index << 8];
          }
        }
        if (!complete) continue;
        const std::uint32_t key = type3_key(cubes_[block[0]].index, cubes_[block[1]].index,
                                            cubes_[block[2]].index, cubes_[block[3]].index);
        const auto it =
            std::lower_bound(blocks.begin(), blocks.end(), key,
                             [](const Type3Block& b, std::uint32_t k) { return b.key < k; });
        if (it == blocks.end() || it->key != key) continue;
        merge_type3_block(block, centre_edges, it->bold_bl_tr);
      }
    }
  }

  // Block cubes BL, BR, TL, TR and the block's centre edge as an edge of each of them
  // (type3_centre_edges); the corner cubes are BL and TR, or BR and TL. Their cut edges other
  // than the centre edge are the block's internal edges that carry a vertex next to the
  // centre vertex (two per corner cube); of those vertices, the ones no earlier collapse
  // absorbed take part (a vertex that absorbed one may lie runs away): the centre vertex goes
  // to the first of them that passes the checks, then, the spec's optional step, each other
  // one that passes them joins it too (on a plane, the block's patches become one polygon).
  // Taking absorbing vertices too would give 0.9 % fewer triangles on the abdomen's bone
  // (57.0 % of MC instead of 57.9 %) by moving vertices outside the block.
  void merge_type3_block(const std::array<std::size_t, 4>& block,
                         const std::array<int, 4>& centre_edges, bool bold_bl_tr) {
    const std::array<int, 2> corners =
        bold_bl_tr ? std::array<int, 2>{0, 3} : std::array<int, 2>{1, 2};
    const VertexId centre = edge_vertex(block[corners[0]], centre_edges[corners[0]]);
    if (find(centre) != centre) return;  // absorbed already: not this block's vertex any more
    std::array<VertexId, 4> inner{};
    int inner_count = 0;
    for (int k : corners) {
      const unsigned cut = kCubeCutEdges[cubes_[block[k]].index];
      for (int e = 0; e < kCubeEdgeCount; ++e) {
        if (e == centre_edges[k] || ((cut >> e) & 1u) == 0) continue;
        assert(inner_count < 4);  // a corner configuration cuts three edges
        const VertexId v = edge_vertex(block[k], e);
        if (find(v) == v) inner[static_cast<std::size_t>(inner_count++)] = v;
      }
    }
    begin_transaction();
    int first = 0;
    while (first < inner_count && !try_collapse(centre, inner[static_cast<std::size_t>(first)])) {
      ++first;
    }
    if (first == inner_count) {
      rollback();
      return;
    }
    const VertexId target = inner[static_cast<std::size_t>(first)];
    for (int i = 0; i < inner_count; ++i) {
      if (i != first) try_collapse(inner[static_cast<std::size_t>(i)], target);
    }
    SmallSet<16> touched;
    touched.insert(target);
    if (!clean_touched_slivers(touched)) {
      ++stats_.rejected_sliver;
      ++stats_.merges_abandoned;
      rollback();
      return;
    }
    commit();
    ++stats_.type3_groups;
  }

  // A block's centre edge as an edge of each of its cubes k (0 = BL, 1 = BR, 2 = TL, 3 = TR):
  // it starts at h + v − (the cube's offset in the block) and runs along w.
  static std::array<int, 4> type3_centre_edges(const Type3Plane& axes) {
    std::array<int, 4> edges{};
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> from = axes.diagonal();
      for (int i = 0; i < 3; ++i) {
        from[i] -= ((k & 1) != 0 ? axes.h[i] : 0) + ((k & 2) != 0 ? axes.v[i] : 0);
      }
      edges[static_cast<std::size_t>(k)] = detail::edge_between(
          detail::vertex_at(from[0], from[1], from[2]),
          detail::vertex_at(from[0] + axes.w[0], from[1] + axes.w[1], from[2] + axes.w[2]));
    }
    return edges;
  }

  // ---- Sliver clean-up (D6) -----------------------------------------------------------------

  // A sliver's middle vertex (opposite its longest edge) lies on that edge; collapsing it onto
  // the nearer end of the edge changes no geometry beyond the sliver's height.
  void remove_slivers() {
    constexpr int kRounds = 5;
    for (int round = 0; round < kRounds; ++round) {
      std::size_t changed = 0;
      for (TriangleId t = 0; t < triangle_.size(); ++t) {
        if (triangle_[t].alive == 0) continue;
        VertexId end = kNoVertex;
        if (collapse_sliver(t, &end)) ++changed;
      }
      if (changed == 0) break;
    }
    for (TriangleId t = 0; t < triangle_.size(); ++t) {
      if (triangle_[t].alive == 0) continue;
      const auto c = current(t);
      P3 n;
      if (is_sliver(position(c[0]), position(c[1]), position(c[2]), &n)) ++stats_.slivers_left;
    }
  }

  bool collapse_sliver(TriangleId t, VertexId* survivor) {
    const auto c = current(t);
    const P3 p[3] = {position(c[0]), position(c[1]), position(c[2])};
    P3 n;
    if (!is_sliver(p[0], p[1], p[2], &n)) return false;
    int middle = 0;
    double longest = -1.0;
    for (int k = 0; k < 3; ++k) {
      const P3 e = sub(p[(k + 2) % 3], p[(k + 1) % 3]);  // the edge opposite corner k
      if (dot3(e, e) > longest) {
        longest = dot3(e, e);
        middle = k;
      }
    }
    const VertexId end0 = c[(middle + 1) % 3];
    const VertexId end1 = c[(middle + 2) % 3];
    const P3 d0 = sub(p[middle], position(end0));
    const P3 d1 = sub(p[middle], position(end1));
    const bool first0 = dot3(d0, d0) <= dot3(d1, d1);
    for (VertexId end : {first0 ? end0 : end1, first0 ? end1 : end0}) {
      if (try_collapse(c[middle], end)) {
        ++stats_.sliver_collapses;
        *survivor = end;
        return true;
      }
    }
    return false;
  }

 private:
  const TriangleMesh& mesh_;
  std::span<const BoundaryCube> cubes_;
  const MergeOptions& options_;
  MergeStats& stats_;
  std::span<const std::uint8_t> frozen_;
  double cos_normal_change_ = 0.0;
  double cos_normal_gradient_ = 0.0;
  double epsilon2_ = 0.0;

  // The mesh and lattice state of the merge.
  // Per vertex and per triangle, what a collapse reads together sits together: the merge is
  // bound by the latency of first touches (one cache line per vertex and per triangle instead
  // of one per array: abdomen, 1 thread, tm 2–4 % faster, same-run A/B).
  std::vector<VertexState> vertex_;
  std::vector<TriangleState> triangle_;
  std::vector<TriangleId> incident_;  // CSR vertex → incident triangles (VertexState::offset)

  std::int32_t y_min_ = 0;
  std::int32_t z_min_ = 0;
  std::int64_t row_length_ = 0;
  std::int64_t z_rows_ = 0;
  std::vector<std::uint32_t> row_start_;
  std::vector<std::uint8_t> flag_;     // FLAG of §4.1, per cube record
  std::vector<std::uint8_t> run_;      // cubes in the run that ends at this cube
  std::vector<std::uint8_t> started_;  // this cube merged with its successor

  // Scratch.
  std::vector<VertexId> pending_witness_;  // witnesses found on moved triangles
  std::vector<std::uint8_t> fan_slot_;  // position of a triangle in the fan checked
  bool in_transaction_ = false;
  std::size_t slivers_at_begin_ = 0;
  std::vector<JournalEntry> journal_;  // collapses of the open transaction (reused buffer)
};



void add_stats(MergeStats& sum, const MergeStats& part) {
  for (std::size_t i = 0; i < sum.cubes_merged_by_type.size(); ++i) {
    sum.cubes_merged_by_type[i] += part.cubes_merged_by_type[i];
  }
  for (std::size_t i = 0; i < sum.merges_by_direction.size(); ++i) {
    sum.merges_by_direction[i] += part.merges_by_direction[i];
  }
  std::size_t MergeStats::*const counters[] = {
      &MergeStats::hexagon_merges,    &MergeStats::minor_merges,
      &MergeStats::runs_capped,       &MergeStats::merges_abandoned,
      &MergeStats::rejected_sliver,   &MergeStats::collapses_tried,
      &MergeStats::collapses_done,    &MergeStats::rejected_boundary,
      &MergeStats::rejected_link,     &MergeStats::rejected_fan_size,
      &MergeStats::rejected_normal,   &MergeStats::rejected_gradient,
      &MergeStats::rejected_distance, &MergeStats::rejected_class_size,
      &MergeStats::sliver_collapses,  &MergeStats::slivers_left,
      &MergeStats::type3_groups,      &MergeStats::rejected_frozen,
      &MergeStats::crossing_rounds,   &MergeStats::vertices_frozen,
      &MergeStats::crossings_left};
  for (auto counter : counters) sum.*counter += part.*counter;
}

}  // namespace

namespace {

// Positions as the crossing test sees them: as to_patient will write them (to_patient itself,
// so the same floats; its winding flip does not change what crosses) when `geometry` is given,
// else as they are. Normals are not needed.
TriangleMesh crossing_space(TriangleMesh mesh, const IndexToPatient* geometry) {
  mesh.normals.clear();
  if (geometry != nullptr) to_patient(mesh, *geometry);
  return mesh;
}

// merge_types, also giving each input vertex's id in the output (id_map may be null), with
// the crossing guard (see "No crossings" in type_merging.h): merge, look for crossing pairs
// among the triangles the merge changed, freeze every input vertex of the classes at their
// corners, merge again from the unchanged input; until no pair is left or nothing new can be
// frozen. `geometry`: where the output will be written (crossings are decided on those floats).
void merge_and_compact(TriangleMesh& mesh, std::span<const BoundaryCube> cubes,
                       const MergeOptions& options, MergeStats* stats,
                       std::vector<VertexId>* id_map, const IndexToPatient* geometry) {
  assert(options.run_cap >= 1 && options.epsilon_voxels >= 0.0);
  MergeStats local;
  std::vector<std::uint8_t> frozen;
  std::vector<VertexId> new_id;
  std::vector<std::uint8_t> changed;
  TriangleMesh merged;
  for (;;) {
    MergeStats round;
    round.triangles_before = mesh.triangles.size();
    round.vertices_before = mesh.positions.size();
    std::vector<VertexId> class_of;  // each input vertex's class, for the guard
    {
      // The merge state (about 80 bytes per MC triangle) goes before the guard's search, so
      // the two are not held at once.
      Merger merger(mesh, cubes, options, round, frozen);
      merger.build();
      merger.merge_all();
      if (options.type3) merger.merge_type3();
      if (options.remove_slivers) merger.remove_slivers();
      merged = merger.result(&new_id, &changed);
      if (options.prevent_crossings) {
        class_of.resize(mesh.positions.size());
        for (VertexId v = 0; v < class_of.size(); ++v) class_of[v] = merger.class_of(v);
      }
    }
    round.triangles_after = merged.triangles.size();
    round.vertices_after = merged.positions.size();
    round.crossing_rounds = local.crossing_rounds;
    round.vertices_frozen = local.vertices_frozen;
    local = round;
    if (!options.prevent_crossings) break;
    const SelfIntersections crossings =
        find_self_intersections(crossing_space(merged, geometry), 0, changed);
    if (crossings.pairs.empty()) break;
    // Output vertex → input vertex (compaction keeps the input order).
    std::vector<VertexId> input_of(merged.positions.size());
    for (VertexId v = 0; v < new_id.size(); ++v) {
      if (new_id[v] != kNoVertex) input_of[new_id[v]] = v;
    }
    std::vector<std::uint8_t> root_hit(mesh.positions.size(), 0);
    for (const auto& pair : crossings.pairs) {
      for (std::uint32_t t : pair) {
        for (VertexId v : merged.triangles[t]) root_hit[input_of[v]] = 1;
      }
    }
    if (frozen.empty()) frozen.assign(mesh.positions.size(), 0);
    std::size_t newly = 0;
    for (VertexId v = 0; v < mesh.positions.size(); ++v) {
      if (frozen[v] == 0 && root_hit[class_of[v]] != 0) {
        frozen[v] = 1;
        ++newly;
      }
    }
    if (newly == 0) {
      // Only MC triangles left crossing (float rounding of the map to patient space): nothing
      // a merge can undo.
      local.crossings_left = crossings.pairs.size();
      break;
    }
    local.vertices_frozen += newly;
    ++local.crossing_rounds;
  }
  mesh = std::move(merged);
  if (id_map != nullptr) *id_map = std::move(new_id);
  if (stats != nullptr) *stats = local;
}

// One piece of extract_type_merged, merged on its own and compacted.
struct MergedPiece {
  TriangleMesh mesh;
  std::size_t shared = 0;     // its first `shared` vertices are the piece below's top slice
  std::vector<VertexId> top;  // its top slice's vertices (ids in `mesh`), in seam order
  MergeStats stats;
  AmbiguityStats ambiguity;
};

MergedPiece merge_piece(const Volume& volume, float iso, const ExtractOptions& extract,
                        const MergeOptions& options, std::int64_t first, std::int64_t last) {
  detail::SurfacePiece piece = detail::extract_layers(volume, iso, extract, first, last);
  MergedPiece out;
  out.shared = piece.shared_vertices;
  out.ambiguity = piece.stats;
  std::vector<VertexId> new_id;
  merge_and_compact(piece.mesh, piece.cubes, options, &out.stats, &new_id, &volume.geometry());
  // Seam vertices lie on the piece's boundary, which merging never changes: all of them stay,
  // in order (compaction keeps the order), the shared ones first.
  for (std::size_t v = 0; v < out.shared; ++v) {
    if (new_id[v] != v) throw std::logic_error("type merging moved a seam vertex");
  }
  for (std::size_t v = piece.top_first; v < piece.top_end; ++v) {
    if (new_id[v] == kNoVertex) throw std::logic_error("type merging dropped a seam vertex");
    out.top.push_back(new_id[v]);
  }
  out.mesh = std::move(piece.mesh);
  return out;
}

// Appends a merged piece to `out`, joining its shared vertices to `seam` (the output ids of
// the top slice of the piece appended before it), and makes `seam` its own top slice.
void append_piece(TriangleMesh& out, const MergedPiece& piece, std::vector<VertexId>& seam) {
  if (piece.shared != seam.size()) {
    throw std::logic_error("type merging: pieces disagree about their seam");
  }
  const std::size_t base = out.positions.size() - piece.shared;  // own vertex v → base + v
  if (base + piece.mesh.positions.size() > std::numeric_limits<VertexId>::max()) {
    throw std::length_error("surface has too many vertices for 32-bit indices");
  }
  auto output_id = [&](VertexId v) {
    return v < piece.shared ? seam[v] : static_cast<VertexId>(base + v);
  };
  const auto own = static_cast<std::ptrdiff_t>(piece.shared);
  out.positions.insert(out.positions.end(), piece.mesh.positions.begin() + own,
                       piece.mesh.positions.end());
  out.normals.insert(out.normals.end(), piece.mesh.normals.begin() + own, piece.mesh.normals.end());
  for (const auto& t : piece.mesh.triangles) {
    out.triangles.push_back({output_id(t[0]), output_id(t[1]), output_id(t[2])});
  }
  std::vector<VertexId> top;
  top.reserve(piece.top.size());
  for (VertexId v : piece.top) top.push_back(output_id(v));
  seam = std::move(top);
}

}  // namespace

void merge_types(TriangleMesh& mesh, std::span<const BoundaryCube> cubes,
                 const MergeOptions& options, MergeStats* stats) {
  merge_and_compact(mesh, cubes, options, stats, nullptr, nullptr);
}

TriangleMesh extract_type_merged(const Volume& volume, float iso, const ExtractOptions& extract,
                                 const MergeOptions& options, MergeStats* stats) {
  assert(volume.samples().size() == static_cast<std::size_t>(volume.size().voxels()));
  if (extract.stats != nullptr) *extract.stats = {};
  MergeStats total;
  TriangleMesh out;
  const std::int64_t layers = detail::cube_layer_count(volume, iso, extract);
  const std::int64_t height =
      options.slab_layers > 0 ? static_cast<std::int64_t>(options.slab_layers) : layers;
  const std::int64_t count = layers > 0 ? (layers + height - 1) / height : 0;
  const unsigned threads = std::max(detail::resolve_threads(options.threads),
                                    detail::resolve_threads(extract.threads));
  // Pieces are made on `threads` threads and appended in order as soon as their predecessors
  // are (make_in_order), so at most threads + 1 merged pieces exist beside the output. The
  // output is reserved ahead from the pieces appended so far (their average size × the pieces
  // in all, plus a fifth): growing it by doubling would copy it, holding it twice, typically
  // at its last and largest growth.
  std::vector<VertexId> seam;
  detail::make_in_order<MergedPiece>(
      static_cast<std::size_t>(count), threads,
      [&](std::size_t i) {
        const auto k = static_cast<std::int64_t>(i);
        return merge_piece(volume, iso, extract, options, k * height,
                           std::min(layers, (k + 1) * height));
      },
      [&](std::size_t i, MergedPiece& piece) {
        const std::size_t vertices =
            out.positions.size() + piece.mesh.positions.size() - piece.shared;
        const std::size_t triangles = out.triangles.size() + piece.mesh.triangles.size();
        if (vertices > out.positions.capacity() || triangles > out.triangles.capacity()) {
          const double scale = 1.2 * static_cast<double>(count) / static_cast<double>(i + 1);
          const auto ahead = [&](std::size_t size) {
            return std::max(size, static_cast<std::size_t>(scale * static_cast<double>(size)));
          };
          out.positions.reserve(ahead(vertices));
          out.normals.reserve(ahead(vertices));
          out.triangles.reserve(ahead(triangles));
        }
        append_piece(out, piece, seam);
        add_stats(total, piece.stats);
        total.triangles_before += piece.stats.triangles_before;
        total.vertices_before += piece.stats.vertices_before - piece.shared;
        if (extract.stats != nullptr) *extract.stats += piece.ambiguity;
      });
  total.triangles_after = out.triangles.size();
  total.vertices_after = out.positions.size();
  if (stats != nullptr) *stats = total;
  return out;
}

}  // namespace typemerge::core
