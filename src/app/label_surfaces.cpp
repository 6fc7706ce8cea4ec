#include "app/label_surfaces.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <numeric>
#include <thread>

#include "app/label_mode.h"

namespace typemerge::app {
namespace {

using Clock = std::chrono::steady_clock;

std::uint64_t box_voxels(const LabelExtent& e) {
  std::uint64_t n = 1;
  for (int a = 0; a < 3; ++a) n *= static_cast<std::uint64_t>(e.max[a] - e.min[a] + 1);
  return n;
}

LabelSurface run_task(const LabelTask& task, double sigma_mm, const PipelineOptions& pipeline) {
  const auto start = Clock::now();
  const core::Volume field = detail::label_field(*task.layer, task.label, task.extent, sigma_mm);
  LabelSurface out{make_surface(field, task.spec, pipeline), 0};
  out.milliseconds = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  return out;
}

}  // namespace

std::vector<LabelSurface> extract_label_surfaces(const std::vector<LabelTask>& tasks,
                                                 double sigma_mm, const PipelineOptions& pipeline,
                                                 unsigned threads) {
  if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
  std::vector<LabelSurface> results(tasks.size());
  if (tasks.size() <= 1 || threads == 1) {
    for (std::size_t t = 0; t < tasks.size(); ++t) results[t] = run_task(tasks[t], sigma_mm, pipeline);
    return results;
  }
  // Largest box first; ties by index (the order only decides who waits, not what is made).
  std::vector<std::size_t> order(tasks.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return box_voxels(tasks[a].extent) > box_voxels(tasks[b].extent);
  });
  PipelineOptions one_thread = pipeline;
  one_thread.threads = 1;
  std::vector<std::exception_ptr> errors(tasks.size());
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i = next++; i < order.size(); i = next++) {
      const std::size_t t = order[i];
      try {
        results[t] = run_task(tasks[t], sigma_mm, one_thread);
      } catch (...) {
        errors[t] = std::current_exception();
      }
    }
  };
  const unsigned workers = static_cast<unsigned>(std::min<std::size_t>(threads, tasks.size()));
  std::vector<std::thread> pool;
  for (unsigned w = 1; w < workers; ++w) pool.emplace_back(work);
  work();
  for (std::thread& thread : pool) thread.join();
  for (const std::exception_ptr& error : errors) {
    if (error) std::rethrow_exception(error);
  }
  return results;
}

}  // namespace typemerge::app
