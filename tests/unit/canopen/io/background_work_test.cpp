// BackgroundWork: work run in a thread of its own, its outcome taken on the event loop.
#include "canopen/io/background_work.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <atomic>
#include <chrono>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>

#include "tests/fixtures/thread_nice.hpp"

namespace oegw::canopen::io {
namespace {

using namespace std::chrono_literals;

// Runs the loop until `done` holds; false if it did not within 10 s (a bound on what must happen,
// not a measurement).
template <class Pred>
bool run_until(EventLoop& loop, Pred done) {
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (!done() && std::chrono::steady_clock::now() < until) loop.run_once(10ms);
  return done();
}

TEST(BackgroundWork, TheWorkRunsInAnotherThreadAndItsResultOnTheLoop) {
  EventLoop loop;
  BackgroundWork<int> work;
  std::thread::id worker;
  std::thread::id taker;
  std::optional<int> got;
  ASSERT_TRUE(work.start(
      loop,
      [&worker] {
        worker = std::this_thread::get_id();
        return 42;
      },
      [&](std::optional<int> r, const std::string& failure) {
        taker = std::this_thread::get_id();
        got = r;
        EXPECT_EQ(failure, "");
      }));
  EXPECT_TRUE(work.busy());
  ASSERT_TRUE(run_until(loop, [&] { return got.has_value(); }));
  EXPECT_EQ(*got, 42);
  EXPECT_NE(worker, std::this_thread::get_id());
  EXPECT_EQ(taker, std::this_thread::get_id());
  EXPECT_FALSE(work.busy());
}

TEST(BackgroundWork, TheLoopServesItsDescriptorsWhileTheWorkIsHeld) {
  EventLoop loop;
  BackgroundWork<int> work;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  bool done = false;
  work.start(
      loop,
      [released] {
        released.wait();
        return 1;
      },
      [&done](std::optional<int>, const std::string&) { done = true; });
  int ticks = 0;
  loop.call_every(loop.now(), 1ms, [&ticks] { ++ticks; });
  ASSERT_TRUE(run_until(loop, [&ticks] { return ticks >= 5; }));
  EXPECT_FALSE(done);
  release.set_value();
  EXPECT_TRUE(run_until(loop, [&done] { return done; }));
}

TEST(BackgroundWork, OneAtATimeAndTheNextMayStartFromTheOutcome) {
  EventLoop loop;
  BackgroundWork<std::string> work;
  std::string seen;
  BackgroundWork<std::string>::Done second = [&seen](std::optional<std::string> r, const std::string&) {
    seen += r.value_or("?");
  };
  ASSERT_TRUE(work.start(
      loop, [] { return std::string("a"); },
      [&](std::optional<std::string> r, const std::string&) {
        seen += r.value_or("?");
        EXPECT_TRUE(work.start(
            loop, [] { return std::string("b"); }, second));
      }));
  EXPECT_FALSE(work.start(
      loop, [] { return std::string("x"); }, second))
      << "a second work while one runs";
  ASSERT_TRUE(run_until(loop, [&seen] { return seen.size() == 2; }));
  EXPECT_EQ(seen, "ab");
}

TEST(BackgroundWork, WhatTheWorkThrowsIsItsOutcome) {
  EventLoop loop;
  BackgroundWork<int> work;
  std::optional<std::string> failure;
  std::optional<int> result{7};
  work.start(
      loop, []() -> int { throw std::runtime_error("disk on fire"); },
      [&](std::optional<int> r, const std::string& f) {
        result = r;
        failure = f;
      });
  ASSERT_TRUE(run_until(loop, [&failure] { return failure.has_value(); }));
  EXPECT_EQ(*failure, "disk on fire");
  EXPECT_FALSE(result.has_value());
}

TEST(BackgroundWork, DestroyedWhileTheWorkRunsItNeitherWaitsNorCallsBack) {
  EventLoop loop;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  auto finished = std::make_shared<std::atomic<bool>>(false);
  bool called = false;
  {
    BackgroundWork<int> work;
    work.start(
        loop,
        [released, finished] {
          released.wait();
          *finished = true;
          return 1;
        },
        [&called](std::optional<int>, const std::string&) { called = true; });
  }  // returns at once although the work is held
  release.set_value();
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (!*finished && std::chrono::steady_clock::now() < until) loop.run_once(1ms);
  EXPECT_TRUE(*finished);
  loop.run_once(0ms);
  EXPECT_FALSE(called);
}

// CAN first: the work's thread may run nicer than the loop's and carries a name (top -H).
TEST(BackgroundWork, TheThreadIsNamedAndNicerThanTheLoop) {
  errno = 0;
  const int loop_nice = ::getpriority(PRIO_PROCESS, 0);
  ASSERT_EQ(errno, 0);
  if (loop_nice >= kMaxNice) GTEST_SKIP() << "this test runs at nice 19: no nicer value to tell the work by";
  EventLoop loop;
  BackgroundWork<int> work;
  std::promise<void> release;
  std::promise<void> running;
  std::shared_future<void> released = release.get_future().share();
  bool done = false;
  work.start(
      loop,
      [&running, released] {
        running.set_value();
        released.wait();
        return 1;
      },
      [&done](std::optional<int>, const std::string&) { done = true; }, {.nice_above = 5, .name = "oegw-test-work"});
  running.get_future().wait();
  const std::optional<int> nice = fixtures::thread_nice("oegw-test-work");
  release.set_value();
  ASSERT_TRUE(nice) << "no thread named oegw-test-work";
  EXPECT_EQ(*nice, std::min(loop_nice + 5, kMaxNice));
  EXPECT_EQ(::getpriority(PRIO_PROCESS, 0), loop_nice) << "the loop's own thread unchanged";
  EXPECT_TRUE(run_until(loop, [&done] { return done; }));
}

// Without a thread (Options::if_no_thread, here forced by no descriptor for the eventfd), the work
// either runs on the loop or fails with the reason, never silently lost.
TEST(BackgroundWork, WithoutAThreadTheWorkRunsOnTheLoopOrFailsWithTheReason) {
  EventLoop loop;
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &old), 0);
  const int lowest_free = ::dup(0);
  ASSERT_GE(lowest_free, 0);
  ::close(lowest_free);
  std::optional<int> on_loop;
  std::string failure_on_loop = "?";
  std::optional<std::string> failure;
  std::thread::id ran_in;
  BackgroundWork<int> a;
  BackgroundWork<int> b;
  rlimit tight = old;
  tight.rlim_cur = static_cast<rlim_t>(lowest_free);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &tight), 0);
  a.start(
      loop,
      [&ran_in] {
        ran_in = std::this_thread::get_id();
        return 3;
      },
      [&](std::optional<int> r, const std::string& f) {
        on_loop = r;
        failure_on_loop = f;
      });
  b.start(
      loop, [] { return 4; }, [&failure](std::optional<int>, const std::string& f) { failure = f; },
      {.if_no_thread = BackgroundWork<int>::IfNoThread::Fail});
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &old), 0);
  loop.run_once(0ms);
  ASSERT_TRUE(on_loop.has_value());
  EXPECT_EQ(*on_loop, 3);
  EXPECT_EQ(failure_on_loop, "");
  EXPECT_EQ(ran_in, std::this_thread::get_id());
  ASSERT_TRUE(failure.has_value());
  EXPECT_NE(failure->find("cannot start a thread for it: eventfd"), std::string::npos) << *failure;
}

}  // namespace
}  // namespace oegw::canopen::io
