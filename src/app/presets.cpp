#include "app/presets.h"

#include <limits>

namespace typemerge::app {

const std::vector<Preset>& presets() {
  constexpr double kNoLimit = std::numeric_limits<double>::infinity();
  // Display colours (sRGB), chosen to look like the tissue and to stay apart when tissues are
  // shown together: the bones ivory and beige, enamel near white, skin tan, muscle red.
  using Srgb = std::array<std::uint8_t, 3>;
  constexpr Srgb kIvory = {0xE3, 0xDA, 0xC9};        // #E3DAC9 "bone"
  constexpr Srgb kSpongyBeige = {0xC8, 0xA9, 0x7E};  // #C8A97E
  constexpr Srgb kEnamelWhite = {0xF8, 0xF8, 0xF0};  // #F8F8F0
  constexpr Srgb kTan = {0xD2, 0xB4, 0x8C};          // #D2B48C CSS "tan"
  constexpr Srgb kFleshPink = {0xE8, 0xA6, 0x96};    // #E8A696
  constexpr Srgb kMuscleRed = {0xA8, 0x3C, 0x32};    // #A83C32
  constexpr Srgb kFatYellow = {0xF2, 0xD0, 0x6B};    // #F2D06B
  constexpr Srgb kLungPink = {0xE3, 0x9F, 0xB6};     // #E39FB6
  static const std::vector<Preset> kPresets = {
      {"bone", 226, kNoLimit, "all bone (InVesalius 'Bone' 226..3071, no upper bound)", kIvory,
       50, false},
      {"compact-bone", 662, 1988, "cortical bone, adult", kIvory, 1000, false},
      {"compact-bone-child", 586, 2198, "cortical bone, child", kIvory, 1000, false},
      {"spongy-bone", 148, 661, "cancellous bone, adult", kSpongyBeige, 1000, false},
      {"spongy-bone-child", 156, 585, "cancellous bone, child", kSpongyBeige, 1000, false},
      {"teeth", 1553, 2850, "enamel, adult", kEnamelWhite, 10, false},
      {"teeth-child", 2042, 3071, "enamel, child", kEnamelWhite, 10, false},
      {"skin", -718, kNoLimit, "outer skin surface, adult (InVesalius lower bound)", kTan, 0, true,
       true},
      {"skin-child", -766, kNoLimit, "outer skin surface, child (InVesalius lower bound)", kTan, 0,
       true, true},
      {"soft-tissue", -700, 225, "all soft tissue", kFleshPink, 10000, false},
      {"muscle", -5, 135, "muscle, adult", kMuscleRed, 1000, false},
      {"muscle-child", -25, 139, "muscle, child", kMuscleRed, 1000, false},
      {"fat", -205, -51, "fat, adult", kFatYellow, 1000, false},
      {"fat-child", -212, -72, "fat, child", kFatYellow, 1000, false},
      {"lung", -1000, -400, "lung parenchyma and airways (air inside the body)", kLungPink, 1000,
       false},
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
