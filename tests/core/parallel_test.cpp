// Tests of the core's threading primitives (parallel.h): make_in_order consumes every result
// once, in order, whatever the thread count and the time each item takes; it never holds more
// than threads + 1 results; and an exception thrown by an item reaches the caller.
#include "core/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <stdexcept>
#include <thread>
#include <vector>

namespace typemerge::core::detail {
namespace {

// An item whose result counts how many results are alive.
struct Counted {
  static std::atomic<int> alive;
  static std::atomic<int> most;
  std::size_t value = 0;
  explicit Counted(std::size_t v) : value(v) { enter(); }
  Counted(const Counted& other) : value(other.value) { enter(); }
  ~Counted() { --alive; }
  Counted& operator=(const Counted&) = default;
  static void enter() {
    const int now = ++alive;
    int seen = most.load();
    while (now > seen && !most.compare_exchange_weak(seen, now)) {
    }
  }
};
std::atomic<int> Counted::alive{0};
std::atomic<int> Counted::most{0};

TEST(MakeInOrder, ConsumesEveryResultOnceInOrderWithBoundedResults) {
  for (unsigned threads : {1u, 2u, 3u, 5u}) {
    SCOPED_TRACE(threads);
    Counted::alive = 0;
    Counted::most = 0;
    std::vector<std::size_t> order;
    constexpr std::size_t kCount = 40;
    make_in_order<Counted>(
        kCount, threads,
        [](std::size_t i) {
          // Early items are slow, so later ones finish first and must wait.
          if (i % 7 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(4));
          return Counted(i * i);
        },
        [&](std::size_t i, Counted& result) {
          EXPECT_EQ(result.value, i * i);
          order.push_back(i);
        });
    ASSERT_EQ(order.size(), kCount);
    for (std::size_t i = 0; i < kCount; ++i) EXPECT_EQ(order[i], i);
    EXPECT_EQ(Counted::alive.load(), 0);
    // One result per thread being made, plus one waiting; a temporary while it is stored.
    EXPECT_LE(Counted::most.load(), static_cast<int>(2 * (threads + 1)));
  }
}

TEST(MakeInOrder, AnExceptionOfAnItemReachesTheCaller) {
  for (unsigned threads : {1u, 2u, 4u}) {
    SCOPED_TRACE(threads);
    std::vector<std::size_t> consumed;
    EXPECT_THROW(make_in_order<int>(
                     100, threads,
                     [](std::size_t i) -> int {
                       if (i == 13) throw std::runtime_error("item 13");
                       return static_cast<int>(i);
                     },
                     [&](std::size_t i, int&) { consumed.push_back(i); }),
                 std::runtime_error);
    // Nothing after the failed item is consumed.
    EXPECT_LE(consumed.size(), 13u);
    for (std::size_t i = 0; i < consumed.size(); ++i) EXPECT_EQ(consumed[i], i);
  }
  // And one thrown by consume.
  EXPECT_THROW(make_in_order<int>(
                   10, 2, [](std::size_t i) { return static_cast<int>(i); },
                   [](std::size_t i, int&) {
                     if (i == 3) throw std::logic_error("consume 3");
                   }),
               std::logic_error);
}

TEST(MakeInOrder, NothingToDo) {
  bool called = false;
  make_in_order<int>(
      0, 4,
      [&](std::size_t) {
        called = true;
        return 0;
      },
      [&](std::size_t, int&) { called = true; });
  EXPECT_FALSE(called);
}

}  // namespace
}  // namespace typemerge::core::detail
