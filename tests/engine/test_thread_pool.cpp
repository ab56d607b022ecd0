#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "engine/thread_pool.hpp"

#if defined(__linux__)
#include <sched.h>
#endif

using namespace marzipan;

// Every call runs each of its items exactly once and returns after the last, also when calls
// follow each other faster than a worker goes to sleep (it picks them up while it looks for
// work) or come after it slept (it is woken).
TEST_CASE("parallelFor runs every item once, back to back and after the workers slept", "[thread_pool]") {
  for (const int threads : {1, 2, 3}) {
    INFO(threads << " threads");
    ThreadPool pool(threads);
    for (int call = 0; call < 2000; ++call) {
      const std::size_t n = std::size_t(1 + call % 13);
      std::vector<std::atomic<int>> ran(n);
      pool.parallelFor(n, [&](std::size_t i) { ran[i].fetch_add(1, std::memory_order_relaxed); });
      int wrong = 0;
      for (auto& r : ran) wrong += r.load() != 1;
      REQUIRE(wrong == 0);
      if (call % 500 == 499) std::this_thread::sleep_for(ThreadPool::kSpin * 3);  // the workers sleep
    }
  }
}

TEST_CASE("parallelFor spreads items over the threads and rethrows the first exception", "[thread_pool]") {
  ThreadPool pool(2);
  // Items that wait for each other meet only if two threads run them at once; the first call
  // of a new pool included (a worker that started after it was made once missed it).
  std::atomic<int> arrived{0}, met{0};
  pool.parallelFor(2, [&](std::size_t) {
    arrived.fetch_add(1);
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (arrived.load() < 2 && std::chrono::steady_clock::now() < until) std::this_thread::yield();
    met.fetch_add(arrived.load() == 2 ? 1 : 0);
  });
  CHECK(met.load() == 2);
  std::atomic<int> done{0};
  CHECK_THROWS_AS(pool.parallelFor(8,
                                   [&](std::size_t i) {
                                     if (i == 5) throw std::runtime_error("item 5");
                                     done.fetch_add(1);
                                   }),
                  std::runtime_error);
  CHECK(done.load() == 7);  // the other items still ran
  // The pool works on after a throw.
  std::atomic<int> after{0};
  pool.parallelFor(16, [&](std::size_t) { after.fetch_add(1); });
  CHECK(after.load() == 16);
}

TEST_CASE("callers of one pool from several threads, and nested calls, all complete", "[thread_pool]") {
  ThreadPool pool(2);
  std::atomic<long> sum{0};
  std::vector<std::thread> callers;
  for (int c = 0; c < 3; ++c)
    callers.emplace_back([&] {
      for (int call = 0; call < 300; ++call)
        pool.parallelFor(4, [&](std::size_t i) {
          pool.parallelFor(3, [&](std::size_t k) { sum.fetch_add(long(i * 3 + k + 1)); });
        });
    });
  for (auto& t : callers) t.join();
  // Each call adds 1 + 2 + ... + 12 = 78.
  CHECK(sum.load() == 3L * 300 * 78);
}

#if defined(__linux__)
// A server started under `taskset -c 0` must count one core, not the machine's: before
// usableCores the pool, the hub's workers and the socket threads all took
// hardware_concurrency() threads, which then took turns on the one core. The check runs on a
// thread of its own so that the test runner's mask stays as it was.
TEST_CASE("usableCores counts the affinity mask, and a default pool follows it", "[thread_pool]") {
  cpu_set_t all;
  CPU_ZERO(&all);
  REQUIRE(sched_getaffinity(0, sizeof all, &all) == 0);
  CHECK(usableCores() == unsigned(CPU_COUNT(&all)));
  int first = 0;
  while (!CPU_ISSET(first, &all)) ++first;
  unsigned pinnedCount = 0;
  int pinnedPool = 0;
  std::thread([&] {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(first, &one);
    if (sched_setaffinity(0, sizeof one, &one) != 0) return;
    pinnedCount = usableCores();
    pinnedPool = ThreadPool(0).threads();
  }).join();
  CHECK(pinnedCount == 1);
  CHECK(pinnedPool == 1);
}
#endif
