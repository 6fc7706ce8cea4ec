// run_parallel and make_in_order: the core's threading primitives. std::thread (std::jthread)
// rather than TBB or OpenMP because typemerge::core is std-only (STYLE.md: no third-party
// dependency in core).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <optional>
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

// Runs make(i) for every i in [0, count) on `threads` threads (the caller's included) and
// hands each result to consume(i, result) in increasing i, as soon as the results before it
// have been consumed (consume runs under a lock, on whichever thread completed the run). A
// thread starts item i only when i <= consumed + threads, so at most threads + 1 results
// exist at once; a slow item holds up the consuming, not the other threads, unlike making
// the items in waves. The first exception stops the handing out and is rethrown here.
template <typename Result, typename Make, typename Consume>
void make_in_order(std::size_t count, unsigned threads, const Make& make, const Consume& consume) {
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<std::optional<Result>> ready(count);
  std::size_t next = 0;
  std::size_t consumed = 0;
  std::exception_ptr error;
  auto worker = [&] {
    std::unique_lock lock(mutex);
    while (true) {
      changed.wait(lock, [&] { return error || next >= count || next <= consumed + threads; });
      if (error || next >= count) return;
      const std::size_t i = next++;
      lock.unlock();
      std::optional<Result> result;
      std::exception_ptr failure;
      try {
        result.emplace(make(i));
      } catch (...) {
        failure = std::current_exception();
      }
      lock.lock();
      if (failure) {
        if (!error) error = failure;
      } else {
        ready[i] = std::move(result);
        try {
          for (; consumed < count && ready[consumed]; ++consumed) {
            consume(consumed, *ready[consumed]);
            ready[consumed].reset();
          }
        } catch (...) {
          if (!error) error = std::current_exception();
        }
      }
      changed.notify_all();
    }
  };
  {
    std::vector<std::jthread> pool;
    for (unsigned t = 1; t < threads && t < count; ++t) pool.emplace_back(worker);
    worker();
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace typemerge::core::detail
