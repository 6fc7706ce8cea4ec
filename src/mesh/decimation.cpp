#include "mesh/decimation.h"

#include <cassert>
#include <chrono>
#include <string>

#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModHausdorffT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include "mesh/detail/openmesh_conversion.h"

namespace typemerge::mesh {

DecimationReport decimate_mesh(core::TriangleMesh& mesh, const DecimationOptions& options) {
  assert(options.max_error > 0.0);
  assert(options.max_normal_deviation > 0.0 && options.max_normal_deviation <= 180.0);
  using detail::OpenMeshTriMesh;

  const auto start = std::chrono::steady_clock::now();
  DecimationReport report;
  report.triangles_before = mesh.triangles.size();
  report.max_error = options.max_error;

  detail::ToOpenMesh converted = detail::to_openmesh(mesh);
  report.split_vertices = converted.split_vertices;
  report.rejected_triangles = converted.rejected_faces;
  if (converted.rejected_faces > 0) {
    report.warnings.push_back("not decimated: " + std::to_string(converted.rejected_faces) +
                              " triangles are on non-manifold or inconsistently oriented edges");
    report.triangles_after = mesh.triangles.size();
    report.validity = check_validity(mesh);
    return report;
  }
  if (converted.skipped_repeated_index > 0) {
    report.warnings.push_back(std::to_string(converted.skipped_repeated_index) +
                              " triangles with a repeated index dropped");
  }

  OpenMeshTriMesh& om = converted.mesh;
  om.request_vertex_status();
  om.request_edge_status();
  om.request_face_status();
  om.request_face_normals();  // before ModNormalFlippingT, which otherwise prints a notice
  om.update_face_normals();

  using Decimater = OpenMesh::Decimater::DecimaterT<OpenMeshTriMesh>;
  Decimater decimater(om);
  OpenMesh::Decimater::ModQuadricT<OpenMeshTriMesh>::Handle quadric;
  OpenMesh::Decimater::ModHausdorffT<OpenMeshTriMesh>::Handle hausdorff;
  OpenMesh::Decimater::ModNormalFlippingT<OpenMeshTriMesh>::Handle flipping;
  decimater.add(quadric);
  decimater.add(hausdorff);
  decimater.add(flipping);
  decimater.module(quadric).unset_max_err();  // priority only
  decimater.module(hausdorff).set_tolerance(options.max_error);
  decimater.module(flipping).set_max_normal_deviation(options.max_normal_deviation);
  const bool initialized = decimater.initialize();
  assert(initialized);
  (void)initialized;

  if (options.target_triangles > 0) {
    decimater.decimate_to_faces(0, options.target_triangles);
  } else {
    decimater.decimate(0);
  }

  mesh = detail::from_openmesh(om);
  remove_unreferenced_vertices(mesh);
  report.triangles_after = mesh.triangles.size();
  report.reached_target =
      options.target_triangles > 0 && report.triangles_after <= options.target_triangles + 1;
  report.openmesh_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  report.validity = check_validity(mesh);
  return report;
}

}  // namespace typemerge::mesh
