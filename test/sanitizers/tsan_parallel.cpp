// ThreadSanitizer driver for the core's parallel global search (built and run by scripts/run_sanitizers.sh).
//
// cv::parallel_for_ splits ImageDifference::compareMany and the census branch of Localizer::computeRow
// across threads from 512 keyframes on, and the map's set-up statistics and the online DTW's window from
// 4096 on. This program searches maps of 600..4200 keyframes with params.parallel = true and checks every
// result against the same search with params.parallel = false, which runs on the calling thread alone.
//
// OpenCV on Debian runs parallel_for_ on TBB, whose task hand-over is lock-free code that is not
// instrumented: ThreadSanitizer would see no happens-before edge between the caller and the workers and
// report races that are not there (or miss real ones). main() therefore installs a plain std::thread pool
// as OpenCV's parallel backend (cv::parallel::setParallelForBackend); its mutex and condition variables
// are visible to ThreadSanitizer, so what it reports is about our code. Run with "opencv" as the first
// argument to keep OpenCV's own backend instead.
#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/core/parallel/parallel_backend.hpp>

#include "along_route_localization/image_difference.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/route_map.h"
#include "../core/synthetic_route.h"

namespace arl = along_route_localization;
using synthetic::randomFrame;
using synthetic::syntheticMap;

namespace
{

/// parallel_for_ on std::threads: the caller and `workers` threads take tasks from a shared counter.
class ThreadPoolBackend : public cv::parallel::ParallelForAPI
{
public:
  explicit ThreadPoolBackend(int workers)
  {
    for (int i = 0; i < workers; ++i)
      threads_.emplace_back([this, i] { workerLoop(i + 1); });
  }

  ~ThreadPoolBackend() override
  {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    work_cv_.notify_all();
    for (std::thread& thread : threads_)
      thread.join();
  }

  void parallel_for(int tasks, FN_parallel_for_body_cb_t body, void* data) override
  {
    std::lock_guard<std::mutex> call(call_mutex_);  // one parallel region at a time
    std::unique_lock<std::mutex> lock(mutex_);
    body_ = body;
    data_ = data;
    next_task_ = 0;
    task_count_ = tasks;
    unfinished_ = tasks;
    work_cv_.notify_all();
    runTasks(lock);
    done_cv_.wait(lock, [this] { return unfinished_ == 0; });
    body_ = nullptr;
    data_ = nullptr;
  }

  int getThreadNum() const override { return thread_index_; }
  int getNumThreads() const override { return static_cast<int>(threads_.size()) + 1; }
  int setNumThreads(int) override { return getNumThreads(); }
  const char* getName() const override { return "std::thread pool (ThreadSanitizer driver)"; }
  /// Tasks run by the pool's own threads so far: shows that a search really went parallel.
  static long tasksOnWorkers() { return tasks_on_workers_.load(); }

private:
  void workerLoop(int index)
  {
    thread_index_ = index;
    std::unique_lock<std::mutex> lock(mutex_);
    while (true)
    {
      work_cv_.wait(lock, [this] { return stop_ || (body_ != nullptr && next_task_ < task_count_); });
      if (stop_)
        return;
      runTasks(lock);
    }
  }

  // Called with `lock` held; runs tasks without it.
  void runTasks(std::unique_lock<std::mutex>& lock)
  {
    while (body_ != nullptr && next_task_ < task_count_)
    {
      const int task = next_task_++;
      const FN_parallel_for_body_cb_t body = body_;
      void* const data = data_;
      lock.unlock();
      body(task, task + 1, data);
      if (thread_index_ != 0)
        ++tasks_on_workers_;
      lock.lock();
      if (--unfinished_ == 0)
        done_cv_.notify_all();
    }
  }

  std::mutex call_mutex_;
  std::mutex mutex_;  // guards everything below
  std::condition_variable work_cv_, done_cv_;
  FN_parallel_for_body_cb_t body_ = nullptr;
  void* data_ = nullptr;
  int next_task_ = 0, task_count_ = 0, unfinished_ = 0;
  bool stop_ = false;
  std::vector<std::thread> threads_;
  static thread_local int thread_index_;
  static std::atomic<long> tasks_on_workers_;
};

thread_local int ThreadPoolBackend::thread_index_ = 0;
std::atomic<long> ThreadPoolBackend::tasks_on_workers_(0);
bool g_thread_pool = false;  // main() installed ThreadPoolBackend

TEST(ParallelSearch, CompareManyEqualsTheSerialSearch)
{
  const int count = 1500;
  const auto map = syntheticMap(count);
  const cv::Mat query = map->keyframeMat(700).clone();
  const long tasks_before = ThreadPoolBackend::tasksOnWorkers();
  for (int first_row : { 0, 5 })
  {
    const arl::ImageDifference difference(map->width(), map->height(), first_row, 4, true);
    std::vector<float> serial_costs(count), serial_shifts(count), costs(count, -1.0f), shifts(count, -99.0f);
    difference.compareMany(query.data, map->data(), count, serial_costs.data(), serial_shifts.data(), false);
    difference.compareMany(query.data, map->data(), count, costs.data(), shifts.data(), true);
    for (int k = 0; k < count; ++k)
    {
      ASSERT_EQ(serial_costs[k], costs[k]) << "keyframe " << k << ", first_row " << first_row;
      ASSERT_EQ(serial_shifts[k], shifts[k]) << "keyframe " << k << ", first_row " << first_row;
    }
    EXPECT_EQ(0.0f, costs[700]);
  }
  if (g_thread_pool)
  {
    EXPECT_GT(ThreadPoolBackend::tasksOnWorkers(), tasks_before) << "no keyframes were compared on a worker thread";
  }
}

// Two localizers over one map, one searching in parallel: every frame must give the same answer. The
// queries are keyframes 300.. in order (the first frames search the whole map), then unknown places
// until the localizer is lost and searches globally again.
void expectParallelEqualsSerial(arl::CostFunction cost_function, int map_size, int frames)
{
  const auto map = syntheticMap(map_size);
  arl::LocalizerParams params;
  params.start_keyframe = -1;  // the start unknown: the first frames search the whole map
  params.cost_function = cost_function;
  params.lost_after_frames = 3;
  // No check of the newest frames while tracking: its whole-map rows are the global search's computeRow,
  // which the frames before and after the loss run anyway, and with it each Localizer measures the map's
  // chance margins on its first check (20 x K whole-map rows), which under ThreadSanitizer took over ten
  // minutes of CI for these two maps.
  params.relocalization_rows = 0;
  // Lost on low confidence, as the driver wants (the unknown places then search globally again); coasting
  // instead (the default), each check would weigh its place against the same chance margins.
  params.loss_needs_contradiction = false;
  params.parallel = false;
  arl::Localizer serial(map, params);
  params.parallel = true;
  arl::Localizer parallel(map, params);
  const long tasks_before = ThreadPoolBackend::tasksOnWorkers();
  for (int i = 0; i < frames; ++i)
  {
    const cv::Mat query = i < frames / 2 ? map->keyframeMat(300 + i).clone() : randomFrame(50000 + i);
    const arl::LocalizationResult a = serial.process(query);
    const arl::LocalizationResult b = parallel.process(query);
    ASSERT_EQ(a.status, b.status) << "frame " << i;
    ASSERT_EQ(a.keyframe, b.keyframe) << "frame " << i;
    ASSERT_EQ(a.confidence, b.confidence) << "frame " << i;
    ASSERT_EQ(a.shift_px, b.shift_px) << "frame " << i;
    if (i > params.min_init_frames && i < frames / 2)
    {
      EXPECT_EQ(300 + i, b.keyframe) << "frame " << i;
    }
  }
  EXPECT_EQ(serial.lastPath(), parallel.lastPath());
  if (g_thread_pool)
  {
    EXPECT_GT(ThreadPoolBackend::tasksOnWorkers(), tasks_before) << "no global search ran on a worker thread";
  }
}

TEST(ParallelSearch, LocalizerSadSearchEqualsTheSerialSearch)
{
  expectParallelEqualsSerial(arl::CostFunction::kSad, 1200, 24);
}

TEST(ParallelSearch, LocalizerCensusSearchEqualsTheSerialSearch)
{
  expectParallelEqualsSerial(arl::CostFunction::kCensus, 600, 16);
}

// From 4096 keyframes on, the set-up's per-keyframe statistics and the global search's online DTW (its
// window split into column chunks; in one piece with params.parallel false) run on several threads too,
// and the global search compares 2x2-averaged images (coarse_search_keyframes).
TEST(ParallelSearch, LocalizerOnAMapOf4096KeyframesOrMoreEqualsTheSerialSearch)
{
  expectParallelEqualsSerial(arl::CostFunction::kSad, 4200, 16);
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  const bool opencv_backend = argc > 1 && std::string(argv[1]) == "opencv";
  if (!opencv_backend)
  {
    cv::parallel::setParallelForBackend(std::make_shared<ThreadPoolBackend>(3));
    g_thread_pool = true;
  }
  std::printf("parallel_for_ backend: %s, %d threads\n",
              opencv_backend ? "OpenCV's own" : "std::thread pool", cv::getNumThreads());
  return RUN_ALL_TESTS();
}
