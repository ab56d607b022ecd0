// marzipan-bench [--threads N] [--quick] [SCENARIO...]: runs the named scenarios (default:
// all) and prints one JSON object per line on stdout.
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <string>
#include <thread>

#include "bench.hpp"

#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define MARZIPAN_BENCH_CALLGRIND 1
#endif

namespace marzipan::bench {

#ifdef MARZIPAN_BENCH_CALLGRIND
bool countingInstructions() { return RUNNING_ON_VALGRIND != 0; }
void toggleInstructionCount() { CALLGRIND_TOGGLE_COLLECT; }
int dumpInstructionCount(int reps) {
  static int measurements = 0;
  const std::string name = "marzipan-bench measurement " + std::to_string(++measurements) + " reps " + std::to_string(reps);
  CALLGRIND_DUMP_STATS_AT(name.c_str());
  return measurements;
}
#else
bool countingInstructions() { return false; }
void toggleInstructionCount() {}
int dumpInstructionCount(int) { return 0; }
#endif

namespace {
std::map<std::string, ScenarioFn>& registry() {
  static std::map<std::string, ScenarioFn> r;
  return r;
}
}  // namespace

Registrar::Registrar(const char* name, ScenarioFn fn) { registry()[name] = std::move(fn); }

void emit(const std::string& scenario, int threads, const Timing& t, nlohmann::ordered_json extra) {
  nlohmann::ordered_json j;
  j["scenario"] = scenario;
  j["threads"] = threads;
  j["median_ms"] = t.median_ms;
  j["min_ms"] = t.min_ms;
  j["max_ms"] = t.max_ms;
  j["reps"] = t.reps;
  j["cpu_median_ms"] = t.cpu_median_ms;
  if (t.measurement) j["measurement"] = t.measurement;
  for (auto& [k, v] : extra.items()) j[k] = v;
  std::cout << j.dump() << std::endl;
}

}  // namespace marzipan::bench

int main(int argc, char** argv) {
  using namespace marzipan::bench;
  Options opt;
  std::vector<std::string> names;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      opt.quick = true;
    } else if (a == "--threads" && i + 1 < argc) {
      opt.threads = std::atoi(argv[++i]);
      if (opt.threads < 0) opt.threads = 0;
    } else if (a == "--list") {
      for (const auto& [name, fn] : registry()) std::cout << name << "\n";
      return 0;
    } else if (a == "-h" || a == "--help") {
      std::cout << "usage: marzipan-bench [--threads N] [--quick] [--list] [SCENARIO...]\n";
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::cerr << "marzipan-bench: unknown option " << a << "\n";
      return 2;
    } else {
      if (!registry().count(a)) {
        std::cerr << "marzipan-bench: unknown scenario " << a << " (see --list)\n";
        return 2;
      }
      names.push_back(a);
    }
  }
  if (opt.threads == 0) opt.threads = int(std::max(1u, std::thread::hardware_concurrency()));
  if (names.empty())
    for (const auto& [name, fn] : registry()) names.push_back(name);
  for (const auto& n : names) registry()[n](opt);
  return 0;
}
