#include "app/presets.h"

#include <limits>

namespace typemerge::app {

const std::vector<Preset>& presets() {
  constexpr double kNoLimit = std::numeric_limits<double>::infinity();
  static const std::vector<Preset> kPresets = {
      {"bone", 226, kNoLimit, "all bone (InVesalius 'Bone' 226..3071, no upper bound)", 50,
       false},
      {"compact-bone", 662, 1988, "cortical bone, adult", 1000, false},
      {"compact-bone-child", 586, 2198, "cortical bone, child", 1000, false},
      {"spongy-bone", 148, 661, "cancellous bone, adult", 1000, false},
      {"spongy-bone-child", 156, 585, "cancellous bone, child", 1000, false},
      {"teeth", 1553, 2850, "enamel, adult", 10, false},
      {"teeth-child", 2042, 3071, "enamel, child", 10, false},
      {"skin", -718, kNoLimit, "outer skin surface, adult (InVesalius lower bound)", 0, true,
       true},
      {"skin-child", -766, kNoLimit, "outer skin surface, child (InVesalius lower bound)", 0,
       true, true},
      {"soft-tissue", -700, 225, "all soft tissue", 10000, false},
      {"muscle", -5, 135, "muscle, adult", 1000, false},
      {"muscle-child", -25, 139, "muscle, child", 1000, false},
      {"fat", -205, -51, "fat, adult", 1000, false},
      {"fat-child", -212, -72, "fat, child", 1000, false},
      {"lung", -1000, -400, "lung parenchyma and airways (air inside the body)", 1000, false},
  };
  return kPresets;
}

std::optional<Preset> find_preset(const std::string& name) {
  for (const Preset& preset : presets()) {
    if (preset.name == name) return preset;
  }
  return std::nullopt;
}

}  // namespace typemerge::app
