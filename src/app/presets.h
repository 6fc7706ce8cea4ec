// Tissue presets: named HU windows for the surfaces people print.
//
// Values are InVesalius's published CT threshold presets (invesalius/presets.py, thresh_ct),
// adult and child where they differ, plus lung/airway and teeth from the Hounsfield scale.
// A window [lo, hi] becomes the surface around the voxels whose value lies inside it.
// Two deliberate departures from InVesalius, both for printable single shells:
// - bone has no upper bound: InVesalius's 3071 is the top of the 12-bit range, not a tissue
//   limit, and cutting there punches holes around metal and in extended-range scanners;
// - skin is everything denser than −718 HU: InVesalius's window −718..−177 selects only the
//   thin air/skin partial-volume layer, whose surface is a broken double shell of thousands
//   of components; its lower bound is kept.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace typemerge::app {

struct Preset {
  std::string name;
  double lo;  // HU, inclusive
  double hi;  // HU, inclusive; +infinity: no upper bound
  std::string description;
  // Display colour (sRGB) of the preset's object in a 3MF package: what the tissue looks like,
  // and distinct where tissues are printed together (bone ivory inside tan skin).
  std::array<std::uint8_t, 3> srgb;
  // Finishing that users otherwise do by hand: drop debris and the scanner table (components
  // under this volume), and for skin keep one outer shell.
  double min_component_mm3 = 0;
  bool fill_cavities = false;
  // Skin is one shell: the largest solid (which drops the scanner table) with its cavities
  // filled (the walls of air inside the body), so exactly one shell is left.
  bool keep_largest = false;
};

const std::vector<Preset>& presets();
std::optional<Preset> find_preset(const std::string& name);

}  // namespace typemerge::app
