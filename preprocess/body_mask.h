// remove_outside_body: clears everything that is not the patient — the scanner table, its
// rails, the mattress, cables, positioning aids — to air before surfaces are extracted.
//
// Users of every peer tool cut the table off the skin and bone surfaces by hand. The table and
// the mattress touch the patient, so component rules on the surface cannot separate them; in
// the volume they can:
//   1. tissue: voxels of fat or denser (> body_threshold_hu, −200). Mattresses, pads and
//      blankets (foam, −900 to −300 HU) fall out here, even where they are wider than the
//      body and touch it over a wide contact.
//   2. seed: the largest 3D component of the tissue after an in-plane opening that cuts thin
//      contacts (a table top a few mm thick touching the back).
//   3. body: the tissue within opening + restore_mm of the seed (thin parts of the patient the
//      opening removed — nose, ears — come back; a board touching the back stays cut unless
//      it is within that distance).
//   4. keep: the body grown by edge_mm in-plane and by one slice, so the partial-volume edge
//      around it (skin at −718 HU lies between tissue and air) is untouched.
// Voxels denser than air (> air_threshold_hu) outside `keep` become air. A pad touching the
// back is thereby cut to a fringe at most edge_mm thick along the contact.
//
// Masks are run-length (preprocess/run_mask.h): a few runs per row, not a byte per voxel, so
// the step costs per run and holds little beside the volume; slices run in parallel. The
// byte-mask version it replaced, with OpenCV's morphology, is kept in the tests as the oracle
// its output is compared with (tests/preprocess/body_mask_oracle.cpp).
#pragma once

#include <cstdint>

#include "core/volume.h"
#include "preprocess/step_record.h"

namespace typemerge::preprocess {

struct BodyMaskOptions {
  // What is cleared outside the body: anything above this. It must lie below every surface
  // threshold used afterwards (skin: −718), or material between the two (a foam pad's)
  // survives outside the body and stays under the skin surface.
  float air_threshold_hu = -950;
  float body_threshold_hu = -200;  // tissue: fat (−100) and denser; foam pads are below
  double opening_mm = 5;           // > 0; radius of the in-plane opening that cuts contacts
  double restore_mm = 3;           // ≥ 0; growth beyond the opening radius that restores thin parts
  double edge_mm = 2;              // ≥ 0; partial-volume edge kept around the body
  // Above this share of the tissue outside the body, the "body" is not one (a phantom, an
  // object scan): nothing is cleared and a warning says so.
  double max_tissue_outside_fraction = 0.15;
};

// Voxels outside the body become −1000 HU. The record says how many voxels were cleared and
// how many components were found; with no body at all the volume is returned unchanged
// with a warning. Throws std::invalid_argument for bad options.
StepResult remove_outside_body(core::Volume volume, const BodyMaskOptions& options = {});

}  // namespace typemerge::preprocess
