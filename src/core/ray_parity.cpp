#include "core/ray_parity.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace typemerge::core {
namespace {

using Point = std::array<double, 3>;

Point sub(const Point& a, const Point& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Point cross(const Point& a, const Point& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Point& a, const Point& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Point to_point(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }

// The ray's direction, and kU, kV = kDirection × kU spanning the plane across it (the grid's).
constexpr Point kDirection = {0.5773502691896258, 0.5612486080160912, 0.5929270612815711};
constexpr Point kU = {0.6970374326528527, -0.7170347393820747, 0.0};
constexpr Point kV = {kDirection[1] * kU[2] - kDirection[2] * kU[1],
                      kDirection[2] * kU[0] - kDirection[0] * kU[2],
                      kDirection[0] * kU[1] - kDirection[1] * kU[0]};

}  // namespace

bool ray_crosses(const Point& origin, const Point& p0, const Point& p1, const Point& p2) {
  const Point e1 = sub(p1, p0);
  const Point e2 = sub(p2, p0);
  const Point h = cross(kDirection, e2);
  const double det = dot(e1, h);
  if (det == 0.0) return false;  // the ray parallel to the plane
  const double inv = 1.0 / det;
  const Point s = sub(origin, p0);
  const double u = dot(s, h) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const Point q = cross(s, e1);
  const double v = dot(kDirection, q) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  return dot(e2, q) * inv > 0.0;
}

RayParity::RayParity(const TriangleMesh& mesh, std::span<const std::uint32_t> ids) : mesh_(mesh) {
  build(ids, false);
}

RayParity::RayParity(const TriangleMesh& mesh) : mesh_(mesh) { build({}, true); }

void RayParity::build(std::span<const std::uint32_t> ids, bool all) {
  struct Shadow {
    std::uint32_t triangle;
    double u_min, u_max, v_min, v_max;
  };
  const std::size_t count = all ? mesh_.triangles.size() : ids.size();
  if (count == 0) return;
  std::vector<Shadow> shadows;
  shadows.reserve(count);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double u_lo = kInf, u_hi = -kInf, v_lo = kInf, v_hi = -kInf;
  for (std::size_t k = 0; k < count; ++k) {
    const auto i = all ? static_cast<std::uint32_t>(k) : ids[k];
    Shadow s{i, kInf, -kInf, kInf, -kInf};
    for (const std::uint32_t vertex : mesh_.triangles[i]) {
      const Point p = to_point(mesh_.positions[vertex]);
      const double u = dot(p, kU);
      const double v = dot(p, kV);
      s.u_min = std::min(s.u_min, u);
      s.u_max = std::max(s.u_max, u);
      s.v_min = std::min(s.v_min, v);
      s.v_max = std::max(s.v_max, v);
    }
    u_lo = std::min(u_lo, s.u_min);
    u_hi = std::max(u_hi, s.u_max);
    v_lo = std::min(v_lo, s.v_min);
    v_hi = std::max(v_hi, s.v_max);
    shadows.push_back(s);
  }
  size_ = std::clamp<std::int64_t>(
      static_cast<std::int64_t>(std::sqrt(static_cast<double>(count) / 2.0)), 1, 2048);
  const double extent = std::max({u_hi - u_lo, v_hi - v_lo, 1e-30});
  const double margin = 1e-9 * extent;
  u0_ = u_lo - 2 * margin;
  v0_ = v_lo - 2 * margin;
  cell_ = (extent + 4 * margin) / static_cast<double>(size_);
  auto cells = [&](const Shadow& s, auto&& visit) {
    const auto clamp_cell = [&](double x, double x0) {
      return std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor((x - x0) / cell_)), 0,
                                      size_ - 1);
    };
    const std::int64_t i0 = clamp_cell(s.u_min - margin, u0_);
    const std::int64_t i1 = clamp_cell(s.u_max + margin, u0_);
    const std::int64_t j0 = clamp_cell(s.v_min - margin, v0_);
    const std::int64_t j1 = clamp_cell(s.v_max + margin, v0_);
    for (std::int64_t j = j0; j <= j1; ++j) {
      for (std::int64_t i = i0; i <= i1; ++i) visit(static_cast<std::size_t>(j * size_ + i));
    }
  };
  start_.assign(static_cast<std::size_t>(size_ * size_) + 1, 0);
  for (const Shadow& s : shadows) cells(s, [&](std::size_t cell) { ++start_[cell + 1]; });
  for (std::size_t k = 1; k < start_.size(); ++k) start_[k] += start_[k - 1];
  triangles_.resize(start_.back());
  std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
  for (const Shadow& s : shadows) {
    cells(s, [&](std::size_t cell) { triangles_[fill[cell]++] = s.triangle; });
  }
}

bool RayParity::inside(const Point& point) const {
  if (size_ == 0) return false;
  const auto i = static_cast<std::int64_t>(std::floor((dot(point, kU) - u0_) / cell_));
  const auto j = static_cast<std::int64_t>(std::floor((dot(point, kV) - v0_) / cell_));
  if (i < 0 || j < 0 || i >= size_ || j >= size_) return false;  // no shadow covers it
  const auto cell = static_cast<std::size_t>(j * size_ + i);
  std::size_t crossings = 0;
  for (std::uint32_t k = start_[cell]; k < start_[cell + 1]; ++k) {
    const auto& t = mesh_.triangles[triangles_[k]];
    if (ray_crosses(point, to_point(mesh_.positions[t[0]]), to_point(mesh_.positions[t[1]]),
                    to_point(mesh_.positions[t[2]]))) {
      ++crossings;
    }
  }
  return crossings % 2 == 1;
}

}  // namespace typemerge::core
