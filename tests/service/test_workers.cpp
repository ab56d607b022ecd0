// Workers and Strand (service/workers.hpp): a strand runs its tasks one at a time, in the order
// posted within each lane, quick ones first.
#include <catch2/catch.hpp>

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "service/workers.hpp"

using namespace marzipan::service;

TEST_CASE("a strand runs its quick tasks before the normal ones waiting, each lane in order", "[workers]") {
  Workers workers(1);
  std::mutex mutex;
  std::condition_variable cv;
  bool released = false;
  std::vector<std::string> ran;
  // The one worker is held, so everything below waits in the strand until it is released.
  workers.post([&] {
    std::unique_lock lock(mutex);
    cv.wait(lock, [&] { return released; });
  });
  auto strand = std::make_shared<Strand>(workers);
  const auto task = [&](std::string name) {
    return [&, name] {
      const std::lock_guard lock(mutex);
      ran.push_back(name);
    };
  };
  strand->post(task("n1"));
  strand->post(task("n2"));
  strand->post(task("q1"), Strand::Lane::Quick);
  strand->post(task("n3"));
  strand->post(task("q2"), Strand::Lane::Quick);
  CHECK(strand->pending() == 6);  // five waiting, and the runOne posted
  {
    const std::lock_guard lock(mutex);
    released = true;
  }
  cv.notify_all();
  workers.stop();  // runs what is queued, the strand's re-posts included
  CHECK(ran == std::vector<std::string>{"q1", "q2", "n1", "n2", "n3"});
  CHECK(strand->pending() == 0);
}
