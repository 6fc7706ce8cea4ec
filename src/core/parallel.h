// run_parallel: the core's one threading primitive. std::thread (std::jthread) rather than TBB
// or OpenMP because typemerge::core is std-only (STYLE.md: no third-party dependency in core).
#pragma once

#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace typemerge::core::detail {

// The thread count an options field asks for: 0 = hardware concurrency, at least 1.
inline unsigned resolve_threads(unsigned requested) {
  const unsigned n = requested != 0 ? requested : std::thread::hardware_concurrency();
  return n != 0 ? n : 1;
}

// Runs job(i, w) for every i in [0, count) on `threads` threads (the caller's included, as
// w = 0; w < threads identifies the worker, e.g. for scratch buffers), handing out indices in
// increasing order from a shared counter. Jobs must write disjoint outputs; results that
// depend only on i are then independent of the thread count.
template <typename Job>
void run_parallel(std::size_t count, unsigned threads, const Job& job) {
  std::atomic<std::size_t> next{0};
  auto worker = [&](unsigned w) {
    for (std::size_t i = next++; i < count; i = next++) job(i, w);
  };
  std::vector<std::jthread> pool;
  for (unsigned t = 1; t < threads && t < count; ++t) pool.emplace_back(worker, t);
  worker(0);
}

}  // namespace typemerge::core::detail
