// The host's own two-thread speed-up, measured beside a benchmark's. On a virtual machine the
// second core is not always a whole core: two copies of a plain CPU loop ran 1.25–2.05 times
// as fast as one copy twice over, minute by minute, on the 2-core host of docs/benchmarks.md,
// and work that streams memory gains less than work in a core's own cache. A two-thread
// figure is then read against what the host gave perfectly parallel work of both kinds in the
// same minutes.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <thread>
#include <vector>

namespace typemerge::bench {

class HostProbe {
 public:
  // Two private arrays of 64 MiB (beyond the caches), mapped here, outside any timing.
  HostProbe()
      : arrays_{std::vector<std::uint32_t>(kWords, 1u), std::vector<std::uint32_t>(kWords, 2u)} {}

  // Wall milliseconds for two units of integer arithmetic over a private 256 KiB buffer (in a
  // core's own cache: the units share nothing but the host), about 100 ms each on that host:
  // one after the other on this thread (threads = 1), or at once on two.
  double cached_ms(unsigned threads) {
    return two_units(threads, [](int) { return cached_unit(); });
  }
  // The same for units that read and write one of the 64 MiB arrays eight times (about 80 ms).
  double streaming_ms(unsigned threads) {
    return two_units(threads, [this](int which) { return streaming_unit(arrays_[which]); });
  }

 private:
  static constexpr std::size_t kWords = std::size_t{16} << 20;

  static std::uint32_t cached_unit() {
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

  static std::uint32_t streaming_unit(std::vector<std::uint32_t>& array) {
    std::uint32_t sum = 0;
    for (int pass = 0; pass < 8; ++pass) {
      for (std::uint32_t& word : array) {
        word += 1;
        sum += word;
      }
    }
    return sum;
  }

  template <typename Unit>
  static double two_units(unsigned threads, const Unit& unit) {
    volatile std::uint32_t sink = 0;
    const auto start = std::chrono::steady_clock::now();
    if (threads >= 2) {
      std::uint32_t other = 0;
      std::thread helper([&other, &unit] { other = unit(1); });
      const std::uint32_t mine = unit(0);
      helper.join();
      sink = mine ^ other;
    } else {
      sink = unit(0) ^ unit(1);
    }
    (void)sink;
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
        .count();
  }

  std::vector<std::uint32_t> arrays_[2];
};

}  // namespace typemerge::bench
