// Connected components of a surface: keep the largest, drop small debris, fill cavities.
//
// Components are connected through shared vertices (as in core::check_mesh), so two shells
// the extractor joined at one lattice-edge vertex are one component. A component's volume
// is its signed enclosed volume by the divergence theorem, in mesh units cubed (mm³ after
// core::to_patient): positive for an outward-wound closed shell (a solid), negative for the
// inward-facing wall of a cavity. Volumes of open components depend on the origin and mean
// little; these functions are meant for closed surfaces.
//
// Removing a component keeps the order of the remaining triangles and vertices; vertices
// no triangle uses afterwards are removed.
#pragma once

#include <cstddef>

#include "core/mesh.h"
#include "mesh/validity.h"

namespace typemerge::mesh {

struct ComponentReport {
  std::size_t components_before = 0;
  std::size_t components_after = 0;
  std::size_t removed_components = 0;
  std::size_t removed_triangles = 0;
  double removed_volume = 0.0;  // sum of |signed volume| of the removed components
  double kept_volume = 0.0;     // signed volume of what is left
  Validity validity;            // of the result
};

enum class Cavities { keep, fill };

// Each function below takes, optionally, check_mesh of `mesh` as it is given (`checked`):
// when that says closed and manifold, the result's validity is derived from it
// (core::check_after_removing_components) instead of checking the result again. `threads`
// (0: all cores) share that check; the result does not depend on it.

// Keeps the largest solid: the outward shell enclosing the most volume (ties: more triangles,
// then the first) with the walls of its own cavities, and removes every other component —
// other solids, their cavities, and islands floating in its cavities. A skull keeps its
// cranial cavity. With Cavities::fill its cavity walls go too: one shell, as fill_cavities
// afterwards would leave it, without searching for them. A mesh with no outward shell keeps
// its component of largest |signed volume|.
ComponentReport keep_largest_component(core::TriangleMesh& mesh,
                                       Cavities cavities = Cavities::keep,
                                       const core::MeshCheck* checked = nullptr,
                                       unsigned threads = 1);

// Removes every component whose |signed volume| is < min_volume (mesh units³, mm³ after
// to_patient). Cavities count by their size too: a cavity smaller than min_volume is filled.
// Precondition: min_volume >= 0.
ComponentReport remove_small_components(core::TriangleMesh& mesh, double min_volume,
                                        const core::MeshCheck* checked = nullptr,
                                        unsigned threads = 1);

// Makes a hollow surface solid, so a skin becomes one shell. The rule:
//  * a component with negative signed volume is a cavity wall (the extractor winds outward
//    from the material, so a void's wall faces into the void) and is removed;
//  * a component with positive volume that lies inside another positive component —
//    decided by the parity of the crossings of a ray from one of its vertices with that
//    component's triangles — is an island inside a cavity (or a nested shell) and is
//    removed as well, since once the cavity is filled it is buried in solid.
// Outermost solids are kept whatever their size.
ComponentReport fill_cavities(core::TriangleMesh& mesh,
                              const core::MeshCheck* checked = nullptr, unsigned threads = 1);

}  // namespace typemerge::mesh
