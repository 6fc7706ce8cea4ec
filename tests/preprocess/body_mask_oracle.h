// remove_outside_body as it was with byte masks and OpenCV's morphology: the slow oracle the
// run-length version is compared with (same options, same output, same record).
#pragma once

#include "core/volume.h"
#include "preprocess/body_mask.h"
#include "preprocess/step_record.h"

namespace typemerge::preprocess::oracle {

StepResult remove_outside_body_with_byte_masks(core::Volume volume,
                                               const BodyMaskOptions& options = {});

}  // namespace typemerge::preprocess::oracle
