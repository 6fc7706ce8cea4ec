#include "mesh/normals.h"

#include <array>
#include <cassert>
#include <cmath>
#include <vector>

namespace typemerge::mesh {

void compute_vertex_normals(core::TriangleMesh& mesh) {
  const std::size_t n = mesh.positions.size();
  std::vector<std::array<double, 3>> sums(n, {0.0, 0.0, 0.0});
  for (const auto& t : mesh.triangles) {
    assert(t[0] < n && t[1] < n && t[2] < n);
    const std::array<double, 3> c = core::triangle_area_vector(mesh, t);
    for (const std::uint32_t v : t) {
      for (int k = 0; k < 3; ++k) sums[v][k] += c[k];
    }
  }
  mesh.normals.assign(n, {0.0f, 0.0f, 0.0f});
  for (std::size_t v = 0; v < n; ++v) {
    const auto& s = sums[v];
    const double length = std::sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    if (length == 0.0) continue;
    mesh.normals[v] = {static_cast<float>(s[0] / length), static_cast<float>(s[1] / length),
                       static_cast<float>(s[2] / length)};
  }
}

}  // namespace typemerge::mesh
