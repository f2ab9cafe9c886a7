// Google Benchmark of the per-frame work: preprocessing, the image difference over the map, the DTW
// update, the whole Localizer::process while tracking and while searching globally, a straightforward
// implementation for comparison, and a memory-read baseline over the same keyframe bytes.
// All data is synthetic with fixed seeds, except the BM_Nordland* pair: the whole real route (1788
// summer keyframes, 1788 winter queries), localized by the Localizer and by the straightforward
// implementation, skipped with a message when the frames are not there. scripts/run_benchmarks runs it
// and prints the ratios.
//
// Names carry the map size as "keyframes:N" so that the script can pair figures of one run.
#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "along_route_localization/contrast_enhancement.h"
#include "along_route_localization/cost_ring_buffer.h"
#include "along_route_localization/homing.h"
#include "along_route_localization/image_difference.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/online_dtw.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"
#include "glue/frame_source.h"

namespace arl = along_route_localization;

namespace
{

constexpr int kWidth = 64;
constexpr int kHeight = 32;
constexpr int kMaxShiftPx = 4;
constexpr int kAnchorSpacing = 8;  // keyframes between two unrelated views of the synthetic route
constexpr uint32_t kSeed = 20240611u;

/// The unnormalized view at keyframe k of a synthetic route: a linear blend of two random "anchor"
/// views, so consecutive keyframes look alike and keyframes more than kAnchorSpacing apart do not.
class SyntheticRoute
{
public:
  void rawView(int keyframe, cv::Mat& view)
  {
    const int anchor = keyframe / kAnchorSpacing;
    const float t = static_cast<float>(keyframe % kAnchorSpacing) / kAnchorSpacing;
    const cv::Mat& a = anchorView(anchor);
    const cv::Mat& b = anchorView(anchor + 1);
    cv::addWeighted(a, 1.0 - t, b, t, 0.0, view, CV_8U);
  }

private:
  const cv::Mat& anchorView(int anchor)
  {
    if (anchor != cached_index_[0] && anchor != cached_index_[1])
    {
      const int slot = anchor % 2;
      cv::RNG rng(kSeed + static_cast<uint64_t>(anchor));
      cached_[slot].create(kHeight, kWidth, CV_8UC1);
      rng.fill(cached_[slot], cv::RNG::UNIFORM, 0, 256);
      cached_index_[slot] = anchor;
    }
    return cached_[cached_index_[0] == anchor ? 0 : 1];
  }

  cv::Mat cached_[2];
  int cached_index_[2] = { -1, -1 };
};

arl::PreprocessingParams mapParams()
{
  arl::PreprocessingParams params;  // 64 x 32, patch normalization, no sky rows
  params.output_width = kWidth;
  params.output_height = kHeight;
  return params;
}

void normalizeLikeThePreprocessor(cv::Mat& image)
{
  const arl::PreprocessingParams params = mapParams();
  arl::patchNormalize(image, params.patch_size, params.min_patch_std, params.output_gain);
}

/// Maps of N keyframes, built once per N and shared by all benchmarks (N = 100k is 200 MB).
std::shared_ptr<const arl::RouteMap> routeMap(int keyframes)
{
  static std::map<int, std::shared_ptr<const arl::RouteMap>> cache;
  auto it = cache.find(keyframes);
  if (it != cache.end())
    return it->second;
  auto map = std::make_shared<arl::RouteMap>(mapParams());
  map->reserve(keyframes);
  SyntheticRoute route;
  cv::Mat view;
  for (int k = 0; k < keyframes; ++k)
  {
    route.rawView(k, view);
    normalizeLikeThePreprocessor(view);
    map->addKeyframe(view, static_cast<int64_t>(k) * 100000000);
  }
  cache[keyframes] = map;
  return map;
}

/// Queries driving along the route: the keyframe's view with Gaussian noise, then normalized.
class QueryStream
{
public:
  explicit QueryStream(int first_keyframe) : next_(first_keyframe), rng_(kSeed) {}

  /// The query for the next keyframe, written into `query` (64 x 32 mono8).
  int next(cv::Mat& query)
  {
    route_.rawView(next_, raw_);
    raw_.convertTo(noisy_, CV_32F);
    for (int y = 0; y < kHeight; ++y)
      for (int x = 0; x < kWidth; ++x)
        noisy_.at<float>(y, x) += static_cast<float>(noise_(rng_));
    noisy_.convertTo(query, CV_8U);
    normalizeLikeThePreprocessor(query);
    return next_++;
  }

private:
  int next_;
  SyntheticRoute route_;
  cv::Mat raw_, noisy_;
  std::mt19937 rng_;
  std::normal_distribution<double> noise_{ 0.0, 8.0 };
};

/// A block of consecutive queries, generated outside the timed region.
struct QueryBlock
{
  std::vector<cv::Mat> frames;
  size_t next = 0;

  void refill(QueryStream& stream, int count)
  {
    frames.resize(count);
    for (cv::Mat& f : frames)
      stream.next(f);
    next = 0;
  }
};

arl::LocalizerParams benchmarkLocalizerParams()
{
  arl::LocalizerParams params;  // defaults: K = 30, m = 4, search radius 40 (a band of 81)
  params.parallel = true;
  params.start_keyframe = -1;  // the synthetic drives start mid-route: a global search, then tracking
  return params;
}

bool isTracking(arl::LocalizationStatus status)
{
  return status == arl::LocalizationStatus::kTracking;
}

const std::vector<int> kMapSizes = { 1000, 10000, 100000 };

void mapSizeArgs(benchmark::internal::Benchmark* b)
{
  b->ArgNames({ "keyframes" });
  for (int n : kMapSizes)
    b->Arg(n);
}

// Every map size against each of `values` of a second argument called `name` (off / on, or a count).
void mapSizeByArgs(benchmark::internal::Benchmark* b, const char* name, std::initializer_list<int> values)
{
  b->ArgNames({ "keyframes", name });
  for (int n : kMapSizes)
    for (int value : values)
      b->Args({ n, value });
}

void mapSizeParallelArgs(benchmark::internal::Benchmark* b)
{
  mapSizeByArgs(b, "parallel", { 0, 1 });
}

// ------------------------------------------------------------------------------------------------
// Step 1: one camera frame (640 x 480) and one already small frame (64 x 32), bgr8 input.

void BM_Preprocess(benchmark::State& state)
{
  const int width = static_cast<int>(state.range(0)), height = static_cast<int>(state.range(1));
  arl::PreprocessingParams params = mapParams();
  params.normalization = state.range(2) == 1 ? arl::NormalizationMethod::kPatch : arl::NormalizationMethod::kDivisive;
  arl::Preprocessor preprocessor(params);
  cv::Mat frame(height, width, CV_8UC3);
  cv::RNG rng(kSeed);
  rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
  cv::Mat output;
  for (auto _ : state)
  {
    preprocessor.process(frame, arl::PixelFormat::kBgr8, output);
    benchmark::DoNotOptimize(output.data);
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * frame.total() * frame.elemSize());
  state.SetLabel(params.normalization == arl::NormalizationMethod::kPatch ? "patch" : "divisive");
}
BENCHMARK(BM_Preprocess)
    ->ArgNames({ "width", "height", "normalization" })
    ->Args({ 640, 480, 1 })
    ->Args({ 640, 480, 2 })
    ->Args({ 64, 32, 1 })
    ->Args({ 64, 32, 2 })
    ->Unit(benchmark::kMicrosecond);

// ------------------------------------------------------------------------------------------------
// Memory-read baseline: every byte of the keyframe buffer once, as 64-bit words so that the loop is
// bound by memory, not by widening adds. Serial, and split across cores like compareMany.

uint64_t sumWords(const uint8_t* bytes, size_t count)
{
  uint64_t sum = 0;
  for (size_t i = 0; i + 8 <= count; i += 8)
  {
    uint64_t word;
    std::memcpy(&word, bytes + i, sizeof(word));  // compiles to a plain load
    sum += word;
  }
  return sum;
}

void BM_MemoryRead(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const bool parallel = state.range(1) != 0;
  const auto map = routeMap(n);
  const size_t bytes = map->keyframeBytes() * map->size();
  const size_t stripe_bytes = 256 * map->keyframeBytes();  // compareMany's stripes
  const int stripes = static_cast<int>((bytes + stripe_bytes - 1) / stripe_bytes);
  std::vector<uint64_t> partial(stripes);
  for (auto _ : state)
  {
    if (parallel)
    {
      cv::parallel_for_(cv::Range(0, stripes), [&](const cv::Range& range) {
        for (int s = range.start; s < range.end; ++s)
        {
          const size_t begin = s * stripe_bytes;
          partial[s] = sumWords(map->data() + begin, std::min(stripe_bytes, bytes - begin));
        }
      });
    }
    else
    {
      partial[0] = sumWords(map->data(), bytes);
    }
    benchmark::DoNotOptimize(partial.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(bytes));
}
BENCHMARK(BM_MemoryRead)->Apply(mapSizeParallelArgs)->UseRealTime()->Unit(benchmark::kMillisecond);

// ------------------------------------------------------------------------------------------------
// Step 2: SAD with a +-4 px shift search of one query against every keyframe of the map.

/// One query (the route's frame n / 2) against the n keyframes of a route map, each iteration.
void runCompareMany(benchmark::State& state, int n, const arl::ImageDifference& difference, bool parallel)
{
  const auto map = routeMap(n);
  QueryStream stream(n / 2);
  cv::Mat query;
  stream.next(query);
  std::vector<float> costs(n), shifts(n);
  for (auto _ : state)
  {
    difference.compareMany(query.data, map->data(), n, costs.data(), shifts.data(), parallel);
    benchmark::DoNotOptimize(costs.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(map->keyframeBytes()) * n);
}

void BM_SadCompareMany(benchmark::State& state)
{
  runCompareMany(state, static_cast<int>(state.range(0)), arl::ImageDifference(kWidth, kHeight, 0, kMaxShiftPx, true),
                 state.range(1) != 0);
}
BENCHMARK(BM_SadCompareMany)->Apply(mapSizeParallelArgs)->UseRealTime()->Unit(benchmark::kMillisecond);

// The tracking band (81 keyframes, one thread) with the compared rows in 1 or 2 bands (shift_bands): the
// same bytes, the shift search run per band.
void BM_SadCompareBand(benchmark::State& state)
{
  runCompareMany(state, 81,
                 arl::ImageDifference(kWidth, kHeight, 0, kMaxShiftPx, true, static_cast<int>(state.range(0))), false);
}
BENCHMARK(BM_SadCompareBand)->ArgNames({ "shift_bands" })->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond);

// The same band with a vertical search of +-V rows (max_vertical_shift_px, for a camera that pitches and
// rolls): 2V + 1 comparisons per shift, each over fewer rows, and none of the level path's prefetching.
void BM_SadCompareBandVertical(benchmark::State& state)
{
  runCompareMany(state, 81,
                 arl::ImageDifference(kWidth, kHeight, 0, kMaxShiftPx, true, 1, static_cast<int>(state.range(0))),
                 false);
}
BENCHMARK(BM_SadCompareBandVertical)->ArgNames({ "max_vertical_shift_px" })->Arg(0)->Arg(1)->Arg(2)
    ->Unit(benchmark::kMicrosecond);

// ------------------------------------------------------------------------------------------------
// The homing estimate (homing.h) of one query against its matched keyframe, once per frame: the
// defaults (+-16 px over the whole width, +-2 rows per column), next to the SAD search above, which
// does +-4 px over a central strip for every keyframe of the band.

void BM_HomingEstimate(benchmark::State& state)
{
  const auto map = routeMap(1000);
  arl::HomingEstimator estimator(kWidth, kHeight, 0);
  QueryStream stream(500);
  cv::Mat query;
  stream.next(query);
  for (auto _ : state)
  {
    const arl::HomingEstimate estimate = estimator.estimate(query.data, map->keyframe(500));
    benchmark::DoNotOptimize(estimate.shift_px);
  }
}
BENCHMARK(BM_HomingEstimate)->Unit(benchmark::kMicrosecond);

// ------------------------------------------------------------------------------------------------
// The straightforward implementation: plain nested loops, every keyframe, every shift, one thread,
// no SIMD (vectorization switched off for this function under GCC), no band.

#if defined(__GNUC__) && !defined(__clang__)
__attribute__((optimize("no-tree-vectorize")))
#endif
void straightforwardRow(const uint8_t* query, const uint8_t* keyframes, int count, float* costs, float* shifts)
{
  const int m = kMaxShiftPx;
  const float pixels = static_cast<float>(kHeight * (kWidth - 2 * m));
  for (int k = 0; k < count; ++k)
  {
    const uint8_t* keyframe = keyframes + static_cast<size_t>(k) * kWidth * kHeight;
    uint32_t best = UINT_MAX;
    int best_shift = 0;
    for (int d = -m; d <= m; ++d)
    {
      uint32_t sum = 0;
      for (int y = 0; y < kHeight; ++y)
        for (int x = m; x < kWidth - m; ++x)
          sum += static_cast<uint32_t>(std::abs(query[y * kWidth + x] - keyframe[y * kWidth + x - d]));
      if (sum < best)
      {
        best = sum;
        best_shift = d;
      }
    }
    costs[k] = static_cast<float>(best) / pixels;
    shifts[k] = static_cast<float>(best_shift);
  }
}

void BM_StraightforwardSad(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const auto map = routeMap(n);
  QueryStream stream(n / 2);
  cv::Mat query;
  stream.next(query);
  std::vector<float> costs(n), shifts(n), reference_costs(n), reference_shifts(n);
  // Same costs as the optimized code (shifts may differ on ties), or the comparison means nothing.
  const arl::ImageDifference difference(kWidth, kHeight, 0, kMaxShiftPx, false);
  const int checked = std::min(n, 2000);
  difference.compareMany(query.data, map->data(), checked, reference_costs.data(), reference_shifts.data());
  straightforwardRow(query.data, map->data(), checked, costs.data(), shifts.data());
  for (int k = 0; k < checked; ++k)
    if (costs[k] != reference_costs[k])
    {
      state.SkipWithError("straightforward and optimized SAD disagree");
      return;
    }
  for (auto _ : state)
  {
    straightforwardRow(query.data, map->data(), n, costs.data(), shifts.data());
    benchmark::DoNotOptimize(costs.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(map->keyframeBytes()) * n);
}
BENCHMARK(BM_StraightforwardSad)->Apply(mapSizeArgs)->UseRealTime()->Unit(benchmark::kMillisecond);

// The straightforward per-frame localizer: the row above over the whole map, eq. 2 contrast
// enhancement, and the DTW over the whole map (K = 30 rows) -- no band, no SIMD, no threads.
void BM_StraightforwardFrame(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const auto map = routeMap(n);
  const arl::LocalizerParams params = benchmarkLocalizerParams();
  arl::CostRingBuffer ring(params.ring_buffer_rows, n);
  arl::OnlineDtw dtw(params.dtw);
  std::vector<float> costs(n), shifts(n);
  QueryStream stream(n / 2);
  cv::Mat query;
  const auto frame = [&]() {
    stream.next(query);
    straightforwardRow(query.data, map->data(), n, costs.data(), shifts.data());
    arl::enhanceContrast(costs.data(), nullptr, n, params.contrast_window, arl::kContrastMinStd,
                         params.contrast_clamp, 0.0f, ring.appendRow(0, n));
    return dtw.match(ring, 0, n, params.ring_buffer_rows, true);
  };
  // Fill the ring buffer with the optimized row (same costs), or the setup alone takes K slow frames.
  const arl::ImageDifference difference(kWidth, kHeight, 0, kMaxShiftPx, true);
  for (int r = 0; r + 1 < params.ring_buffer_rows; ++r)
  {
    stream.next(query);
    difference.compareMany(query.data, map->data(), n, costs.data(), shifts.data(), true);
    arl::enhanceContrast(costs.data(), nullptr, n, params.contrast_window, arl::kContrastMinStd,
                         params.contrast_clamp, 0.0f, ring.appendRow(0, n));
  }
  int keyframe = 0;
  for (auto _ : state)
  {
    const arl::SequenceMatch match = frame();
    keyframe = match.keyframe;
    benchmark::DoNotOptimize(keyframe);
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(map->keyframeBytes()) * n);
}
BENCHMARK(BM_StraightforwardFrame)->Apply(mapSizeArgs)->UseRealTime()->Unit(benchmark::kMillisecond);

// ------------------------------------------------------------------------------------------------
// Step 4: the DTW update alone, K = 30 rows, a band of 81 keyframes moving one keyframe per row.

// `rows` rows of random normalized costs in [-2, 2), `width` keyframes each, the first row starting at
// keyframe `first` and each next one `step` keyframes later.
void fillRing(arl::CostRingBuffer* ring, int rows, int first, int step, int width)
{
  std::mt19937 rng(kSeed);
  std::uniform_real_distribution<float> cost(-2.0f, 2.0f);
  for (int r = 0; r < rows; ++r)
  {
    float* row = ring->appendRow(first + r * step, width);
    for (int i = 0; i < width; ++i)
      row[i] = cost(rng);
  }
}

void BM_DtwMatch(benchmark::State& state)
{
  const int band = static_cast<int>(state.range(0));
  const arl::LocalizerParams params = benchmarkLocalizerParams();
  const int rows = params.ring_buffer_rows;
  arl::CostRingBuffer ring(rows, 10000);
  fillRing(&ring, rows, 1000, 1, band);
  arl::OnlineDtw dtw(params.dtw);
  const int newest_first = 1000 + rows - 1;
  for (auto _ : state)
  {
    arl::SequenceMatch match = dtw.match(ring, newest_first, band, rows, true);
    benchmark::DoNotOptimize(match);
  }
  state.counters["rows"] = rows;
}
BENCHMARK(BM_DtwMatch)->ArgNames({ "band" })->Arg(81)->Unit(benchmark::kMicrosecond);

// The DTW of a global search: K = 30 rows over the whole map, not backtracked (as the Localizer's global
// searches), its window split into column chunks on the cores (parallel 1, the default) or in one piece
// (parallel 0; the result is the same).
void BM_DtwWholeMap(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const arl::LocalizerParams params = benchmarkLocalizerParams();
  const int rows = params.ring_buffer_rows;
  arl::CostRingBuffer ring(rows, n);
  fillRing(&ring, rows, 0, 0, n);
  arl::OnlineDtw dtw(params.dtw);
  dtw.setParallel(state.range(1) != 0);
  for (auto _ : state)
  {
    arl::SequenceMatch match = dtw.match(ring, 0, n, rows, false);
    benchmark::DoNotOptimize(match);
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * n * rows);
}
BENCHMARK(BM_DtwWholeMap)->Apply(mapSizeParallelArgs)->UseRealTime()->Unit(benchmark::kMillisecond);

// ------------------------------------------------------------------------------------------------
// Steps 2-5: Localizer::process while tracking along the route.

constexpr int kStartKeyframe = 100;
constexpr int kQueryBlock = 1024;

/// Feeds queries from kStartKeyframe until the localizer tracks; false if it never does.
bool startTracking(arl::Localizer& localizer, QueryStream& stream, int* keyframe)
{
  cv::Mat query;
  for (int frame = 0; frame < 50; ++frame)
  {
    *keyframe = stream.next(query);
    const arl::LocalizationResult result = localizer.process(query);
    if (isTracking(result.status) && std::abs(result.keyframe - *keyframe) <= 1)
      return true;
  }
  return false;
}

// newest_check 0: relocalization_rows 0, the band alone every frame (the paper's tracking). 1: the
// defaults, whose check of the newest frames (Localizer::recentCheck, for a kidnapped robot) compares
// them with the whole map on the frames whose newest rows alone do not support the track: a global
// search's cost on those frames, so the mean per frame grows with the map.
void BM_LocalizerTracking(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const auto map = routeMap(n);
  arl::LocalizerParams params = benchmarkLocalizerParams();
  if (state.range(1) == 0)
    params.relocalization_rows = 0;
  arl::Localizer localizer(map, params);
  std::unique_ptr<QueryStream> stream(new QueryStream(kStartKeyframe));
  int keyframe = 0;
  if (!startTracking(localizer, *stream, &keyframe))
  {
    state.SkipWithError("the localizer does not track the synthetic route");
    return;
  }
  // Blocks short enough that a block never reaches the end of the route (end_of_route is not tracking).
  const int block_size = std::min(kQueryBlock, n / 2);
  QueryBlock block;
  block.refill(*stream, block_size);
  keyframe += 1;  // of block.frames[0]
  int64_t not_tracking = 0, wrong = 0;
  for (auto _ : state)
  {
    if (block.next == block.frames.size())
    {
      state.PauseTiming();
      if (keyframe + 2 * block_size >= n)  // near the end of the route: start over at the beginning
      {
        localizer.reset();
        stream.reset(new QueryStream(kStartKeyframe));
        if (!startTracking(localizer, *stream, &keyframe))
        {
          state.SkipWithError("the localizer does not track the synthetic route after a reset");
          break;
        }
        keyframe += 1;
      }
      block.refill(*stream, block_size);
      state.ResumeTiming();
    }
    const arl::LocalizationResult result = localizer.process(block.frames[block.next++]);
    not_tracking += isTracking(result.status) ? 0 : 1;
    wrong += std::abs(result.keyframe - keyframe) <= 1 ? 0 : 1;
    ++keyframe;
  }
  if (not_tracking > 0)
    state.SkipWithError("the localizer stopped tracking during the benchmark");
  state.counters["frames_not_tracking"] = static_cast<double>(not_tracking);
  state.counters["frames_off_by_more_than_1"] = static_cast<double>(wrong);
  state.SetItemsProcessed(state.iterations());
}
// Wrapping back to the start of the route happens in paused time, so the times stay comparable across N.
void mapSizeNewestCheckArgs(benchmark::internal::Benchmark* b)
{
  mapSizeByArgs(b, "newest_check", { 0, 1 });
}
BENCHMARK(BM_LocalizerTracking)->Apply(mapSizeNewestCheckArgs)->UseRealTime()->Unit(benchmark::kMicrosecond);

// Global relocalization: a localizer that never leaves the initializing state, so every frame
// computes the whole-map row (parallel compareMany), contrast enhancement and the whole-map DTW.
// coarse = 1: on halved images (coarse_search_keyframes = 1), 0: full size.
void BM_GlobalRelocalization(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const auto map = routeMap(n);
  arl::LocalizerParams params = benchmarkLocalizerParams();
  params.init_confirm_frames = 10000;  // global answers, never confirmed
  params.coarse_search_keyframes = state.range(1) ? 1 : 0;
  arl::Localizer localizer(map, params);
  QueryStream stream(kStartKeyframe);
  QueryBlock block;
  block.refill(stream, 256);
  for (int r = 0; r < params.ring_buffer_rows; ++r)  // a full ring buffer, as after K lost frames
    localizer.process(block.frames[block.next++]);
  int wrong = 0;
  for (auto _ : state)
  {
    if (block.next == block.frames.size())
    {
      state.PauseTiming();
      block.refill(stream, 256);
      state.ResumeTiming();
    }
    const arl::LocalizationResult result = localizer.process(block.frames[block.next++]);
    wrong += result.keyframe >= 0 ? 0 : 1;
  }
  state.counters["frames_without_answer"] = wrong;
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(map->keyframeBytes()) * n);
}
void mapSizeCoarseArgs(benchmark::internal::Benchmark* b)
{
  mapSizeByArgs(b, "coarse", { 0, 1 });
}
BENCHMARK(BM_GlobalRelocalization)->Apply(mapSizeCoarseArgs)->UseRealTime()->Unit(benchmark::kMillisecond);

// The first frame after a loss: with relocalization_rows = 8 it computes the whole-map rows of the 8
// frames before it as well as its own (Localizer::process), with 0 only its own. Per iteration, untimed:
// track 40 frames of the route, then show frames of nowhere (random views, normalized) until the track
// is lost. Timed: the next frame, back on the route. Global searches coarse where the localizer's
// default says (coarse_search_keyframes 4096).
void BM_FirstFrameAfterALoss(benchmark::State& state)
{
  const int n = static_cast<int>(state.range(0));
  const auto map = routeMap(n);
  arl::LocalizerParams params = benchmarkLocalizerParams();
  params.relocalization_rows = static_cast<int>(state.range(1));
  arl::Localizer localizer(map, params);
  QueryStream stream(kStartKeyframe);
  cv::RNG rng(kSeed);
  cv::Mat query(kHeight, kWidth, CV_8UC1), nowhere(kHeight, kWidth, CV_8UC1);
  int not_lost = 0;
  for (auto _ : state)
  {
    localizer.reset();
    for (int i = 0; i < 40; ++i)
    {
      stream.next(query);
      localizer.process(query);
    }
    arl::LocalizationStatus status = arl::LocalizationStatus::kTracking;
    for (int i = 0; i < 50 && status != arl::LocalizationStatus::kLost; ++i)
    {
      rng.fill(nowhere, cv::RNG::UNIFORM, 0, 256);
      normalizeLikeThePreprocessor(nowhere);
      status = localizer.process(nowhere).status;
    }
    not_lost += status == arl::LocalizationStatus::kLost ? 0 : 1;
    stream.next(query);
    const auto start = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(localizer.process(query));
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  state.counters["not_lost"] = not_lost;  // iterations whose frames of nowhere did not lose the track
}
void mapSizeReplayArgs(benchmark::internal::Benchmark* b)
{
  mapSizeByArgs(b, "relocalization_rows", { 0, 8 });
}
BENCHMARK(BM_FirstFrameAfterALoss)->Apply(mapSizeReplayArgs)->UseManualTime()->Iterations(20)->Unit(benchmark::kMillisecond);

// ------------------------------------------------------------------------------------------------
// The real route: every winter query of the Nordland frames against the 1788 summer keyframes, frame
// aligned (the truth of query q is keyframe q). Frames are read and preprocessed once, outside the
// timed loops, as localize_offline does (cv::imread unchanged, default PreprocessingParams); the timed
// loop is what localize_offline times as "localizing": constructing the Localizer and process() per
// query. Its loading (PNG decoding) is timed end to end by scripts/run_benchmarks.

#ifndef ALONG_ROUTE_SOURCE_DIR
#define ALONG_ROUTE_SOURCE_DIR "."
#endif

struct NordlandRoute
{
  std::string folder;
  std::string error;  // empty when loaded
  std::shared_ptr<arl::RouteMap> map;
  std::vector<cv::Mat> queries;
};

/// $ALONG_ROUTE_NORDLAND, else ../shared/data/nordland beside the package's source folder.
std::string nordlandFolder()
{
  const char* env = std::getenv("ALONG_ROUTE_NORDLAND");
  if (env && *env)
    return env;
  return std::string(ALONG_ROUTE_SOURCE_DIR) + "/../shared/data/nordland";
}

/// Loaded once and shared by the BM_Nordland* benchmarks.
const NordlandRoute& nordlandRoute()
{
  static NordlandRoute route;
  static bool loaded = false;
  if (loaded)
    return route;
  loaded = true;
  route.folder = nordlandFolder();
  // The frame source of localize_offline itself (src/glue/frame_source.h): the same decoding and
  // preprocessing as the runner.
  try
  {
    arl::PreprocessingParams params;  // localize_offline's defaults
    route.map = arl::loadMapFromPath(route.folder + "/summer", "", &params);
    route.queries = arl::loadPreprocessedFrames(route.folder + "/winter", "", params);
    if (route.map->size() != route.queries.size())
      route.error = "Nordland summer/ and winter/ in " + route.folder + " hold different numbers of frames";
  }
  catch (const std::exception& e)
  {
    route.error = std::string("Nordland frames not loaded (set ALONG_ROUTE_NORDLAND to the folder holding "
                              "summer/ and winter/): ") + e.what();
  }
  return route;
}

/// Frames answered within one keyframe of the truth (query index), over all queries.
double shareWithinOne(const std::vector<int>& keyframes)
{
  size_t within = 0;
  for (size_t q = 0; q < keyframes.size(); ++q)
    within += keyframes[q] >= 0 && std::abs(keyframes[q] - static_cast<int>(q)) <= 1 ? 1 : 0;
  return keyframes.empty() ? 0.0 : static_cast<double>(within) / keyframes.size();
}

/// localize_offline's loop: a Localizer with the default parameters (parallel global searches) fed
/// every query in order. `global_searches` counts the frames whose row covered the whole map: global
/// searches, and the first K frames from the known start, which a global search checks alongside.
std::vector<int> localizeRoute(const NordlandRoute& route, int* global_searches)
{
  arl::Localizer localizer(route.map, arl::LocalizerParams());
  std::vector<int> keyframes(route.queries.size());
  *global_searches = 0;
  for (size_t q = 0; q < route.queries.size(); ++q)
  {
    const arl::LocalizationResult result = localizer.process(route.queries[q]);
    keyframes[q] = result.keyframe;
    *global_searches += localizer.costs().rowWidth(0) == static_cast<int>(route.map->size()) ? 1 : 0;
  }
  return keyframes;
}

void BM_NordlandLocalizer(benchmark::State& state)
{
  const NordlandRoute& route = nordlandRoute();
  if (!route.error.empty())
  {
    state.SkipWithError(route.error.c_str());
    return;
  }
  std::vector<int> keyframes;
  int global_searches = 0;
  for (auto _ : state)
  {
    keyframes = localizeRoute(route, &global_searches);
    benchmark::DoNotOptimize(keyframes.data());
  }
  state.counters["keyframes"] = static_cast<double>(route.map->size());
  state.counters["queries"] = static_cast<double>(route.queries.size());
  state.counters["within_1"] = shareWithinOne(keyframes);
  state.counters["global_search_frames"] = global_searches;
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(route.queries.size()));
}
BENCHMARK(BM_NordlandLocalizer)->UseRealTime()->Unit(benchmark::kMillisecond);

// The straightforward implementation of the same run (as BM_StraightforwardFrame, on the real frames):
// every query against every keyframe with the plain-loop row, eq. 2 over the whole row and the DTW over
// the whole map, one thread. It searches globally on every frame and has none of the Localizer's
// refinements (sub-pixel shift, energy-normalized cost, featureless and stationary handling), so its
// answers differ: both accuracies are reported (within_1), and how often the two agree.
void BM_NordlandStraightforward(benchmark::State& state)
{
  const NordlandRoute& route = nordlandRoute();
  if (!route.error.empty())
  {
    state.SkipWithError(route.error.c_str());
    return;
  }
  const arl::RouteMap& map = *route.map;
  const int n = static_cast<int>(map.size());
  if (map.width() != kWidth || map.height() != kHeight || map.params().skyRows() != 0)
  {
    state.SkipWithError("the straightforward row is written for 64 x 32 frames without sky rows");
    return;
  }
  const arl::LocalizerParams params = arl::LocalizerParams();  // localize_offline's defaults
  std::vector<float> costs(n), shifts(n), reference_costs(n), reference_shifts(n);
  // Its row is the Localizer's raw SAD row (integer shifts, before energy normalization), or the
  // comparison means nothing: checked on a few real queries against the optimized code.
  const arl::ImageDifference difference(kWidth, kHeight, 0, kMaxShiftPx, false);
  for (size_t q = 0; q < route.queries.size(); q += 300)
  {
    difference.compareMany(route.queries[q].data, map.data(), n, reference_costs.data(), reference_shifts.data());
    straightforwardRow(route.queries[q].data, map.data(), n, costs.data(), shifts.data());
    if (costs != reference_costs)
    {
      state.SkipWithError("straightforward and optimized SAD disagree on the Nordland frames");
      return;
    }
  }
  int global_searches = 0;
  const std::vector<int> localizer_keyframes = localizeRoute(route, &global_searches);
  std::vector<int> keyframes(route.queries.size());
  for (auto _ : state)
  {
    arl::CostRingBuffer ring(params.ring_buffer_rows, n);
    arl::OnlineDtw dtw(params.dtw);
    for (size_t q = 0; q < route.queries.size(); ++q)
    {
      straightforwardRow(route.queries[q].data, map.data(), n, costs.data(), shifts.data());
      arl::enhanceContrast(costs.data(), nullptr, n, params.contrast_window, arl::kContrastMinStd,
                           params.contrast_clamp, 0.0f, ring.appendRow(0, n));
      keyframes[q] = dtw.match(ring, 0, n, params.ring_buffer_rows, true).keyframe;
    }
    benchmark::DoNotOptimize(keyframes.data());
  }
  size_t agree = 0;
  for (size_t q = 0; q < keyframes.size(); ++q)
    agree += std::abs(keyframes[q] - localizer_keyframes[q]) <= 1 ? 1 : 0;
  state.counters["keyframes"] = n;
  state.counters["queries"] = static_cast<double>(route.queries.size());
  state.counters["within_1"] = shareWithinOne(keyframes);
  state.counters["localizer_within_1"] = shareWithinOne(localizer_keyframes);
  state.counters["agree_with_localizer_within_1"] = static_cast<double>(agree) / keyframes.size();
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * static_cast<int64_t>(route.queries.size()));
}
BENCHMARK(BM_NordlandStraightforward)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
