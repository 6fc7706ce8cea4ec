#include "io/preview_png.h"

#include <opencv2/core.hpp>
#include <png.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "io/atomic_file.h"

namespace typemerge::io {
namespace {

using Point = std::array<double, 3>;

// One view: which patient axes map to image right, image up and depth (towards the viewer).
struct View {
  int right_axis;
  double right_sign;
  int up_axis;
  int depth_axis;
  double depth_sign;  // the viewer sits at −depth_sign·∞ on depth_axis
};

// Anterior: viewer at −y (anterior), looking along +y; right = +x (patient left), up = +z.
// Left lateral: viewer at +x (patient left), looking along −x; right = −y (anterior), up = +z.
constexpr View kAnterior{0, 1.0, 2, 1, 1.0};
constexpr View kLeftLateral{1, -1.0, 2, 0, -1.0};

void render(const core::TriangleMesh& mesh, const View& view, const std::array<Point, 2>& box,
            int size, cv::Mat& image, int x_offset) {
  const double width = box[1][view.right_axis] - box[0][view.right_axis];
  const double height = box[1][view.up_axis] - box[0][view.up_axis];
  const double scale = 0.92 * size / std::max({width, height, 1e-9});
  const double cx = 0.5 * (box[0][view.right_axis] + box[1][view.right_axis]);
  const double cy = 0.5 * (box[0][view.up_axis] + box[1][view.up_axis]);
  auto project = [&](const std::array<float, 3>& p) {
    return Point{size / 2.0 + view.right_sign * (p[view.right_axis] - cx) * scale,
                 size / 2.0 - (p[view.up_axis] - cy) * scale,
                 view.depth_sign * p[view.depth_axis]};  // smaller is nearer
  };
  std::vector<double> depth(static_cast<std::size_t>(size) * size,
                            std::numeric_limits<double>::infinity());
  for (const auto& t : mesh.triangles) {
    const Point a = project(mesh.positions[t[0]]);
    const Point b = project(mesh.positions[t[1]]);
    const Point c = project(mesh.positions[t[2]]);
    // Shade by the facet normal in patient space against a light from the viewer and above.
    const Point n = core::facet_normal(mesh, t);
    if (n[0] == 0 && n[1] == 0 && n[2] == 0) continue;
    Point light{0, 0, 0.5};
    light[view.depth_axis] = -view.depth_sign;  // towards the viewer
    const double light_length = std::sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2]);
    const double lambert = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / light_length;
    const double shade = 0.15 + 0.85 * std::max(0.0, lambert);

    const double area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    if (area == 0) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a[0], b[0], c[0]}))));
    const int x1 = std::min(size - 1, static_cast<int>(std::ceil(std::max({a[0], b[0], c[0]}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a[1], b[1], c[1]}))));
    const int y1 = std::min(size - 1, static_cast<int>(std::ceil(std::max({a[1], b[1], c[1]}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5, py = y + 0.5;
        const double w0 = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / area;
        const double w1 = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / area;
        const double w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const double z = w0 * a[2] + w1 * b[2] + w2 * c[2];
        double& stored = depth[static_cast<std::size_t>(y) * size + x];
        if (z >= stored) continue;
        stored = z;
        const auto grey = static_cast<unsigned char>(std::clamp(shade * 235.0, 0.0, 255.0));
        image.at<cv::Vec3b>(y, x + x_offset) =
            cv::Vec3b(static_cast<unsigned char>(grey * 0.85), static_cast<unsigned char>(grey * 0.95), grey);
      }
    }
  }
}

}  // namespace

void write_preview_png(const core::TriangleMesh& mesh, const std::filesystem::path& path,
                       const PreviewOptions& options) {
  const int size = options.view_pixels;
  cv::Mat image(size, 2 * size, CV_8UC3, cv::Scalar(48, 40, 32));
  const core::BoundingBox bounds = core::bounding_box(mesh);
  const std::array<Point, 2> box{bounds.min, bounds.max};
  if (!mesh.positions.empty()) {
    render(mesh, kAnterior, box, size, image, 0);
    render(mesh, kLeftLateral, box, size, image, size);
  }
  // libpng's simplified API rather than OpenCV's imgcodecs: in Debian, imgcodecs pulls in
  // GDAL and 138 other shared libraries, which cost every typemerge process about 100 ms at
  // start-up (120 → ~20 ms for `typemerge --version`), and a batch starts one per study.
  png_image header{};
  header.version = PNG_IMAGE_VERSION;
  header.width = static_cast<png_uint_32>(image.cols);
  header.height = static_cast<png_uint_32>(image.rows);
  header.format = PNG_FORMAT_BGR;
  const auto stride = static_cast<png_int_32>(image.step[0]);
  png_alloc_size_t bytes = 0;
  if (!png_image_write_to_memory(&header, nullptr, &bytes, 0, image.data, stride, nullptr)) {
    throw std::runtime_error(std::string("PNG encoding failed: ") + header.message);
  }
  std::vector<unsigned char> png(bytes);
  if (!png_image_write_to_memory(&header, png.data(), &bytes, 0, image.data, stride, nullptr)) {
    throw std::runtime_error(std::string("PNG encoding failed: ") + header.message);
  }
  png_image_free(&header);
  AtomicFile file(path);
  file.write(png.data(), bytes);
  file.commit();
}

}  // namespace typemerge::io
