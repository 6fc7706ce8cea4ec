// extract_label_surfaces: label mode's surfaces, one per label, made on several threads.
//
// Each label's surface depends on its own field alone (detail::label_field on its padded box,
// then make_surface with the pipeline's options), so labels are independent tasks: workers take
// the next label from a shared counter, largest box first (the longest tasks start first), and
// write its result into the label's own slot. The results are therefore the same, byte for
// byte, for any number of threads and any order in which the tasks finish; with one label,
// the threads go to that label's extraction instead (whose output does not depend on them
// either). An exception of a task is rethrown after all tasks ended — the one of the lowest
// label index, so the message does not depend on timing either.
//
// Memory: per running task one label's two fields (its padded box, 4 bytes a voxel each) and
// its surface; at most `threads` tasks at once.
#pragma once

#include <cstdint>
#include <vector>

#include "app/label_census.h"
#include "app/surface_pipeline.h"
#include "core/volume.h"

namespace typemerge::app {

struct LabelTask {
  const core::Volume* layer = nullptr;  // the label map layer holding the label
  std::int32_t label = 0;
  LabelExtent extent;  // its index box (label_census)
  SurfaceSpec spec;    // name, colour; lo = detail::kLabelIso
};

struct LabelSurface {
  SurfaceResult result;
  double milliseconds = 0;  // field and surface, on its worker
};

// One result per task, in the tasks' order. `threads`: 0 = all cores.
std::vector<LabelSurface> extract_label_surfaces(const std::vector<LabelTask>& tasks,
                                                 double sigma_mm, const PipelineOptions& pipeline,
                                                 unsigned threads);

}  // namespace typemerge::app
