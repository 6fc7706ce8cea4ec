// The host's own two-thread speed-up, measured beside a benchmark's. On a virtual machine the
// second core is not always a whole core: two copies of a plain CPU loop ran 1.25–2.05 times
// as fast as one copy twice over, minute by minute, on the 2-core host of docs/benchmarks.md.
// A two-thread figure is then read against what the host gave perfectly parallel work in the
// same minutes.
#pragma once

#include <chrono>
#include <cstdint>
#include <thread>
#include <vector>

namespace typemerge::bench {

// One unit of perfectly parallel work: integer arithmetic over a private 256 KiB buffer (in
// a core's own cache, so the units share nothing but the host), about 100 ms on that host.
inline std::uint32_t host_work_unit() {
  std::vector<std::uint32_t> buffer(std::size_t{1} << 16, 1u);
  std::uint32_t state = 2463534242u;
  for (int pass = 0; pass < 600; ++pass) {
    for (std::uint32_t& word : buffer) {
      state ^= state << 13;
      state ^= state >> 17;
      state ^= state << 5;
      word += state;
      state += word;
    }
  }
  return state;
}

// Wall milliseconds for two units: one after the other on this thread (threads = 1), or one
// on this thread and one on another at once (threads = 2).
inline double two_host_units_ms(unsigned threads) {
  volatile std::uint32_t sink = 0;
  const auto start = std::chrono::steady_clock::now();
  if (threads >= 2) {
    std::uint32_t other = 0;
    std::thread helper([&other] { other = host_work_unit(); });
    const std::uint32_t mine = host_work_unit();
    helper.join();
    sink = mine ^ other;
  } else {
    sink = host_work_unit() ^ host_work_unit();
  }
  (void)sink;
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

}  // namespace typemerge::bench
