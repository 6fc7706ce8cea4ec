// remove_outside_body: clears everything that is not the patient — the scanner table, its
// rails, the mattress, cables, positioning aids — to air before surfaces are extracted.
//
// Users of every peer tool cut the table off the skin and bone surfaces by hand. The table
// touches the patient, so component rules on the surface cannot separate them; in the
// volume they can: the body is the largest 3D component of "denser than air" after an
// in-plane opening that cuts thin contacts (a mattress seam, a table top a few mm thick); it
// is then grown back by the opening radius plus a margin, inside the original mask, so the
// patient's own surface is untouched except where it is thinner than the opening (tips of
// the nose and ears are kept by the growth; detached fingers would not be).
//
// Memory: the volume, three byte masks and a 32-bit component label per voxel.
#pragma once

#include <cstdint>

#include "core/volume.h"
#include "preprocess/step_record.h"

namespace typemerge::preprocess {

struct BodyMaskOptions {
  float air_threshold_hu = -500;  // "denser than air": between air (−1000) and fat (−100)
  double opening_mm = 5;          // > 0; radius of the in-plane opening that cuts contacts
  double margin_mm = 3;           // ≥ 0; extra growth kept around the body
};

// Voxels outside the body become −1000 HU. The record says how many voxels were cleared and
// how many components were found; with no body at all the volume is returned unchanged
// with a warning. Throws std::invalid_argument for bad options.
StepResult remove_outside_body(core::Volume volume, const BodyMaskOptions& options = {});

}  // namespace typemerge::preprocess
