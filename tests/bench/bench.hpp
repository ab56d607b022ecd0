// The benchmark harness: scenarios register themselves by name and print one JSON object per
// line (at least scenario, threads, median_ms, min_ms, max_ms, reps, then their own figures).
//
// Instruction counts (tests/bench/instructions.py): under callgrind started with
// --collect-atstart=no, measure() (and each series of measurePair()) collects only the calls it
// times and dumps them as one part, "marzipan-bench measurement N reps R"; the line that
// reports a Timing then carries "measurement": N (a scenario reporting a second Timing names it
// "<what>_measurement"), which the wrapper turns into instructions per call. Outside callgrind
// nothing changes.
#pragma once

#include <algorithm>
#include <chrono>
#include <ctime>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace marzipan::bench {

struct Options {
  int threads = 0;     // as given on the command line (0 = all cores)
  bool quick = false;  // a short smoke run: small sizes, few repetitions
};

struct Timing {
  double median_ms = 0, min_ms = 0, max_ms = 0;
  int reps = 0;
  // The median CPU time of the process over the reps, all threads together: on a machine shared
  // with other work it stays near the quiet figure when the wall-clock time does not.
  double cpu_median_ms = 0;
  int measurement = 0;  // its callgrind part, 0 when not counting instructions
};

// Under callgrind: whether instructions are counted, collection on or off around a timed call,
// and the dump of one measurement's calls (its number). Elsewhere: false, nothing, 0.
bool countingInstructions();
void toggleInstructionCount();
int dumpInstructionCount(int reps);

inline double processCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

// A Timing of per-call wall and CPU times (ms), in the order they were taken.
inline Timing timingOf(std::vector<double> ms, std::vector<double> cpu, int measurement) {
  std::sort(ms.begin(), ms.end());
  std::sort(cpu.begin(), cpu.end());
  return {ms[ms.size() / 2], ms.front(), ms.back(), int(ms.size()), cpu[cpu.size() / 2], measurement};
}

// One timed call of f: wall and CPU ms appended, and collected when instructions are counted.
template <class F>
void timeCall(F&& f, bool counting, std::vector<double>& ms, std::vector<double>& cpu) {
  const double c0 = processCpuMs();
  const auto t0 = std::chrono::steady_clock::now();
  if (counting) toggleInstructionCount();
  f();
  if (counting) toggleInstructionCount();
  ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  cpu.push_back(processCpuMs() - c0);
}

// Runs setup() then f() `reps` times; only f is timed.
template <class Setup, class F>
Timing measure(int reps, Setup&& setup, F&& f) {
  std::vector<double> ms, cpu;
  const bool counting = countingInstructions();
  for (int r = 0; r < reps; ++r) {
    setup();
    timeCall(f, counting, ms, cpu);
  }
  return timingOf(std::move(ms), std::move(cpu), counting ? dumpInstructionCount(reps) : 0);
}

// Two series taken in turn, setupA(), fA(), setupB(), fB() `reps` times, for a ratio of their
// times: the machine's speed drifts (these VMs' by up to 40% from one run to the next, and
// within a run), and a drift then falls on both series alike, where two series one after the
// other each took a stretch of their own (a tentacle's move against the dab read 2.2-2.9x in
// runs of one binary, 2026-11-30). `pairRatio` gets the median of fA's time over fB's, call by
// call. Under callgrind the series run one after the other, each its own measurement (the
// counts do not drift).
template <class SetupA, class FA, class SetupB, class FB>
std::pair<Timing, Timing> measurePair(int reps, SetupA&& setupA, FA&& fA, SetupB&& setupB, FB&& fB, double* pairRatio) {
  if (countingInstructions()) {
    *pairRatio = 0;
    Timing a = measure(reps, setupA, fA);
    return {a, measure(reps, setupB, fB)};
  }
  std::vector<double> msA, cpuA, msB, cpuB, ratios;
  for (int r = 0; r < reps; ++r) {
    setupA(), timeCall(fA, false, msA, cpuA);
    setupB(), timeCall(fB, false, msB, cpuB);
    ratios.push_back(msA.back() / msB.back());
  }
  std::sort(ratios.begin(), ratios.end());
  *pairRatio = ratios[ratios.size() / 2];
  return {timingOf(std::move(msA), std::move(cpuA), 0), timingOf(std::move(msB), std::move(cpuB), 0)};
}
template <class F>
Timing measure(int reps, F&& f) {
  return measure(reps, [] {}, std::forward<F>(f));
}

// One output line: {"scenario":..., "threads":..., timing..., extra...}.
void emit(const std::string& scenario, int threads, const Timing& t, nlohmann::ordered_json extra = {});

using ScenarioFn = std::function<void(const Options&)>;
struct Registrar {
  Registrar(const char* name, ScenarioFn fn);
};

}  // namespace marzipan::bench

// Defines a scenario: MARZIPAN_BENCH("name") { ... uses `opt` ... }
#define MARZIPAN_BENCH_CAT2(a, b) a##b
#define MARZIPAN_BENCH_CAT(a, b) MARZIPAN_BENCH_CAT2(a, b)
#define MARZIPAN_BENCH(name)                                                                         \
  static void MARZIPAN_BENCH_CAT(benchFn, __LINE__)(const ::marzipan::bench::Options& opt);          \
  static ::marzipan::bench::Registrar MARZIPAN_BENCH_CAT(benchReg, __LINE__)(                        \
      name, MARZIPAN_BENCH_CAT(benchFn, __LINE__));                                                  \
  static void MARZIPAN_BENCH_CAT(benchFn, __LINE__)([[maybe_unused]] const ::marzipan::bench::Options& opt)
