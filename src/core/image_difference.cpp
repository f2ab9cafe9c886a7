#include "along_route_localization/image_difference.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace along_route_localization
{

std::string toString(CostFunction cost)
{
  return cost == CostFunction::kCensus ? "census" : "sad";
}

bool costFunctionFromString(const std::string& name, CostFunction* cost)
{
  if (name == "sad")
    *cost = CostFunction::kSad;
  else if (name == "census")
    *cost = CostFunction::kCensus;
  else
    return false;
  return true;
}

namespace
{

/// Sum of |a[i] - b[i]| over n bytes.
inline uint32_t sadBytesScalar(const uint8_t* a, const uint8_t* b, int n)
{
  uint32_t sum = 0;
  for (int i = 0; i < n; ++i)
    sum += static_cast<uint32_t>(std::abs(static_cast<int>(a[i]) - static_cast<int>(b[i])));
  return sum;
}

#if CV_SIMD128
/// Sum of absolute differences of 16-byte vectors. The universal intrinsics offer it only reduced to
/// a scalar (v_reduce_sad: a shuffle, an add and a move per vector); on x86, psadbw accumulates into
/// two 64-bit lanes in one instruction, which makes the whole-map search 1.5x faster.
class SadAccumulator
{
public:
#if CV_SSE2
  void add(const cv::v_uint8x16& a, const cv::v_uint8x16& b) { sum_ = _mm_add_epi64(sum_, _mm_sad_epu8(a.val, b.val)); }
  uint32_t total() const
  {
    return static_cast<uint32_t>(_mm_cvtsi128_si32(sum_)) +
           static_cast<uint32_t>(_mm_cvtsi128_si32(_mm_unpackhi_epi64(sum_, sum_)));
  }

private:
  __m128i sum_ = _mm_setzero_si128();
#else
  void add(const cv::v_uint8x16& a, const cv::v_uint8x16& b) { sum_ += cv::v_reduce_sad(a, b); }
  uint32_t total() const { return sum_; }

private:
  uint32_t sum_ = 0;
#endif
};

/// Lane i of a load at kTailMask + t is 0xff when i >= 16 - t: keeps the last t lanes of a vector.
alignas(16) const uint8_t kTailMask[32] = { 0,    0,    0,    0,    0,    0,    0,    0,    0,    0,    0,
                                            0,    0,    0,    0,    0,    0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
                                            0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff };

/// How a strip row ends after its full 16-byte vectors.
enum TailKind
{
  kNoTail,      ///< the strip is a multiple of 16 bytes
  kTail8,       ///< exactly 8 bytes: 8-byte loads, so two rows' tails share one vector
  kMaskedTail,  ///< 1..15 bytes: a vector ending at the strip's end, earlier lanes masked out
};

/// SADs at shifts first_shift .. first_shift + count - 1 of a strip `columns` bytes wide
/// (columns >= 16), rows [first_row, height) of images `width` bytes wide. kBlocks > 0 fixes the
/// number of full vectors per row at compile time so that the row is unrolled; 0 reads it at run time.
template <int kBlocks, TailKind kTail>
void sadsSimd(const uint8_t* query, const uint8_t* keyframe, int width, int first_row, int height, int max_shift,
              int columns, int first_shift, int count, uint32_t* sums)
{
  const int blocks = kBlocks > 0 ? kBlocks : columns / 16;
  const cv::v_uint8x16 tail_mask = cv::v_load(kTailMask + columns % 16);
  const uint8_t* q_first = query + static_cast<size_t>(first_row) * width + max_shift;
  for (int i = 0; i < count; ++i)
  {
    const uint8_t* q = q_first;
    const uint8_t* k = keyframe + static_cast<size_t>(first_row) * width + max_shift - (first_shift + i);
    SadAccumulator sum;
    int y = first_row;
    if (kTail == kTail8)
    {
      // Two rows at a time: their 8-byte tails share one vector (64 px, m = 4: 7 SADs instead of 8).
      for (; y + 1 < height; y += 2, q += 2 * width, k += 2 * width)
      {
        for (int b = 0; b < blocks; ++b)
          sum.add(cv::v_load(q + 16 * b), cv::v_load(k + 16 * b));
        for (int b = 0; b < blocks; ++b)
          sum.add(cv::v_load(q + width + 16 * b), cv::v_load(k + width + 16 * b));
        sum.add(cv::v_combine_low(cv::v_load_low(q + columns - 8), cv::v_load_low(q + width + columns - 8)),
                cv::v_combine_low(cv::v_load_low(k + columns - 8), cv::v_load_low(k + width + columns - 8)));
      }
    }
    for (; y < height; ++y, q += width, k += width)
    {
      for (int b = 0; b < blocks; ++b)
        sum.add(cv::v_load(q + 16 * b), cv::v_load(k + 16 * b));
      if (kTail == kTail8)  // the upper lanes of both operands are zero
        sum.add(cv::v_load_low(q + columns - 8), cv::v_load_low(k + columns - 8));
      else if (kTail == kMaskedTail)
        sum.add(cv::v_load(q + columns - 16) & tail_mask, cv::v_load(k + columns - 16) & tail_mask);
    }
    sums[i] = sum.total();
  }
}

template <TailKind kTail>
void sadsSimdBlocks(const uint8_t* query, const uint8_t* keyframe, int width, int first_row, int height,
                    int max_shift, int columns, int first_shift, int count, uint32_t* sums)
{
  switch (columns / 16)
  {
    case 1:
      return sadsSimd<1, kTail>(query, keyframe, width, first_row, height, max_shift, columns, first_shift, count,
                                sums);
    case 2:
      return sadsSimd<2, kTail>(query, keyframe, width, first_row, height, max_shift, columns, first_shift, count,
                                sums);
    case 3:  // 64 px with m = 4: 56 = 3 * 16 + 8
      return sadsSimd<3, kTail>(query, keyframe, width, first_row, height, max_shift, columns, first_shift, count,
                                sums);
    case 4:
      return sadsSimd<4, kTail>(query, keyframe, width, first_row, height, max_shift, columns, first_shift, count,
                                sums);
    default:
      return sadsSimd<0, kTail>(query, keyframe, width, first_row, height, max_shift, columns, first_shift, count,
                                sums);
  }
}
#endif

#if defined(__x86_64__) && defined(__GNUC__)
#define ALONG_ROUTE_AVX512_SAD 1

/// AVX-512BW kernel, chosen at run time, for strips of at most 64 columns: a strip row fits one
/// register. Each query row is loaded once and compared with the keyframe row at kShifts shifts, one
/// accumulator per shift (psadbw: 8 lanes of 8-byte sums): one instruction per row and shift instead
/// of 3.5 with 16-byte vectors (whole-map search at 1k keyframes: 290 -> 180 ns per keyframe).
/// The query row is loaded masked to the strip (zeros beyond it). The keyframe loads are plain
/// 64-byte loads that run past the strip's end: the lanes holding those bytes are left out of the total
/// when the strip is a whole number of lanes; otherwise, and where a plain load could leave the image
/// (the last rows), the keyframe loads are masked to the strip too.
/// Each row also prefetches the same row of the next keyframe: spread this way, the prefetches keep
/// memory busy during the whole search (1.25x faster at 100k keyframes than all 32 at once).
template <int kShifts, bool kMaskedKeyframe>
__attribute__((target("avx512bw"), always_inline)) inline void addRowSadsAvx512(const uint8_t* query_row,
                                                                              const uint8_t* keyframe_row,
                                                                              const uint8_t* next_row,
                                                                              __mmask64 strip, __m512i* sums)
{
  __builtin_prefetch(next_row);
  const __m512i q = _mm512_maskz_loadu_epi8(strip, query_row);
  for (int i = 0; i < kShifts; ++i)  // shift i reads keyframe_row - i: constant offsets, no index register
  {
    const __m512i k = kMaskedKeyframe ? _mm512_maskz_loadu_epi8(strip, keyframe_row - i) :
                                        _mm512_loadu_si512(keyframe_row - i);
    sums[i] = _mm512_add_epi64(sums[i], _mm512_sad_epu8(q, k));
  }
}

/// sums[i] = the total of the first `lanes` 64-bit lanes of acc[i], for i in [0, kShifts).
template <int kShifts>
__attribute__((target("avx512bw"), always_inline)) inline void storeLaneSums(const __m512i* acc, int lanes,
                                                                            uint32_t* sums)
{
  alignas(64) uint64_t lane[kShifts][8];
  for (int i = 0; i < kShifts; ++i)
    _mm512_store_si512(lane[i], acc[i]);
  for (int i = 0; i < kShifts; ++i)
  {
    uint64_t total = 0;
    for (int l = 0; l < lanes; ++l)
      total += lane[i][l];
    sums[i] = static_cast<uint32_t>(total);
  }
}

/// Needs count >= kShifts.
template <int kShifts>
__attribute__((target("avx512bw"))) void sadsAvx512(const uint8_t* query, const uint8_t* keyframe, int width,
                                                    int first_row, int height, int max_shift, int columns,
                                                    int first_shift, int count, uint32_t* sums,
                                                    const uint8_t* next)
{
  const __mmask64 strip = columns >= 64 ? ~static_cast<__mmask64>(0) : (static_cast<__mmask64>(1) << columns) - 1;
  const int lanes = (columns + 7) / 8;
  // Plain loads start at most 2m bytes into a row; rows [first_row, plain_end) keep them inside the image.
  int plain_end = first_row;
  const int room = height * width - 2 * max_shift - 64;
  if (columns % 8 == 0 && room >= 0)
    plain_end = std::min(height, std::max(first_row, room / width + 1));
  const size_t first = static_cast<size_t>(first_row) * width + max_shift;
  for (int done = 0; done < count; done += kShifts)
  {
    const int start = std::min(done, count - kShifts);  // a last, partial pass overlaps the previous one
    __m512i acc[kShifts];
    for (int i = 0; i < kShifts; ++i)
      acc[i] = _mm512_setzero_si512();
    const uint8_t* q = query + first;
    const uint8_t* k = keyframe + first - (first_shift + start);  // shift first_shift + start + i at k - i
    const uint8_t* n = next + first;
    int y = first_row;
    for (; y < plain_end; ++y, q += width, k += width, n += width)
      addRowSadsAvx512<kShifts, false>(q, k, n, strip, acc);
    for (; y < height; ++y, q += width, k += width, n += width)
      addRowSadsAvx512<kShifts, true>(q, k, n, strip, acc);
    storeLaneSums<kShifts>(acc, lanes, sums + start);
  }
}

/// The same for narrow images (width + strip <= 64 bytes, e.g. the 32x16 images of the coarse global
/// search): one register holds the strips of two consecutive rows (lanes [0, strip) and
/// [width, width + strip)), so each row pair costs one load and psadbw per shift. All loads are masked.
template <int kShifts>
__attribute__((target("avx512bw"))) void sadsAvx512TwoRows(const uint8_t* query, const uint8_t* keyframe, int width,
                                                           int first_row, int height, int max_shift, int columns,
                                                           int first_shift, int count, uint32_t* sums,
                                                           const uint8_t* next)
{
  const __mmask64 one_row = (static_cast<__mmask64>(1) << columns) - 1;
  const __mmask64 two_rows = one_row | (one_row << width);
  const size_t first = static_cast<size_t>(first_row) * width + max_shift;
  for (int done = 0; done < count; done += kShifts)
  {
    const int start = std::min(done, count - kShifts);  // a last, partial pass overlaps the previous one
    __m512i acc[kShifts];
    for (int i = 0; i < kShifts; ++i)
      acc[i] = _mm512_setzero_si512();
    const uint8_t* q = query + first;
    const uint8_t* k = keyframe + first - (first_shift + start);
    const uint8_t* n = next + first;
    int y = first_row;
    for (; y + 1 < height; y += 2, q += 2 * width, k += 2 * width, n += 2 * width)
      addRowSadsAvx512<kShifts, true>(q, k, n, two_rows, acc);
    if (y < height)
      addRowSadsAvx512<kShifts, true>(q, k, n, one_row, acc);
    storeLaneSums<kShifts>(acc, 8, sums + start);  // masked loads: every lane holds strip bytes only
  }
}

bool hasAvx512bw()
{
  static const bool supported = __builtin_cpu_supports("avx512bw");
  return supported;
}
#endif

/// Geometry of the compared strip, fixed per ImageDifference.
struct Strip
{
  int width, first_row, height, max_shift;

  int columns() const { return width - 2 * max_shift; }

  /// sums[i] = SAD of the strip at shift first_shift + i, for i in [0, count). `next`, if set, is the
  /// keyframe compared after this one: its compared rows are prefetched meanwhile (compareMany streams
  /// the map once per search, and the hardware prefetcher stops at 4 KB page ends, every 2 keyframes).
  void sads(const uint8_t* query, const uint8_t* keyframe, int first_shift, int count, uint32_t* sums,
            const uint8_t* next = nullptr) const
  {
    const int strip = columns();
#ifdef ALONG_ROUTE_AVX512_SAD
    if (strip <= 64 && hasAvx512bw())
    {
      next = next ? next : keyframe;  // prefetches of the rows being read: no branch in the kernel
      if (width + strip <= 64 && count >= 5)
      {
        if (count >= 9)
          sadsAvx512TwoRows<9>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums,
                               next);
        else
          sadsAvx512TwoRows<5>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums,
                               next);
      }
      else if (count >= 9)  // 2m + 1 with the default m = 4
        sadsAvx512<9>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums, next);
      else if (count >= 5)  // 2m + 1 with m = 2 (the coarse global search)
        sadsAvx512<5>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums, next);
      else
        sadsAvx512<1>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums, next);
      return;
    }
#endif
#if defined(__GNUC__)
    if (next)
      for (size_t offset = static_cast<size_t>(first_row) * width; offset < static_cast<size_t>(height) * width;
           offset += 64)
        __builtin_prefetch(next + offset);
#endif
#if CV_SIMD128
    if (strip >= 16)
    {
      const int tail = strip % 16;
      if (tail == 0)
        sadsSimdBlocks<kNoTail>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums);
      else if (tail == 8)
        sadsSimdBlocks<kTail8>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count, sums);
      else
        sadsSimdBlocks<kMaskedTail>(query, keyframe, width, first_row, height, max_shift, strip, first_shift, count,
                                    sums);
      return;
    }
#endif
    for (int i = 0; i < count; ++i)
    {
      const int shift = first_shift + i;
      uint32_t sum = 0;
      for (int y = first_row; y < height; ++y)
      {
        const uint8_t* q = query + static_cast<size_t>(y) * width + max_shift;
        sum += sadBytesScalar(q, keyframe + static_cast<size_t>(y) * width + max_shift - shift, strip);
      }
      sums[i] = sum;
    }
  }
};

inline uint32_t hammingBytes(const uint8_t* a, const uint8_t* b, int n)
{
  uint32_t sum = 0;
  for (int i = 0; i < n; ++i)
    sum += static_cast<uint32_t>(__builtin_popcount(static_cast<unsigned>(a[i] ^ b[i])));
  return sum;
}

/// Picks the best of the 2m + 1 costs (ties go to the smallest |d|: with no evidence of a rotation,
/// report none) and refines the shift with the parabola through it and its neighbours.
template <typename Cost>
ShiftedDifference pickBestShift(const Cost* cost, int max_shift_px, float divisor, bool subpixel)
{
  const int shifts = 2 * max_shift_px + 1;
  int best = 0;
  for (int i = 1; i < shifts; ++i)
    if (cost[i] < cost[best] || (cost[i] == cost[best] && std::abs(i - max_shift_px) < std::abs(best - max_shift_px)))
      best = i;
  ShiftedDifference result;
  result.cost = static_cast<float>(cost[best]) / divisor;
  double shift = best - max_shift_px;
  if (subpixel && best > 0 && best < shifts - 1)
  {
    const double left = cost[best - 1], centre = cost[best], right = cost[best + 1];
    const double curvature = left - 2.0 * centre + right;
    if (curvature > 0.0)
      shift += 0.5 * (left - right) / curvature;
  }
  result.shift_px = static_cast<float>(shift);
  return result;
}

/// Step 2 with a vertical search (ImageDifference, max_vertical_shift_px V > 0): in each band, for every
/// vertical offset v in [-V, V], the band's query rows y whose keyframe row y - v is a compared row too,
/// at every shift; each shift's per-pixel cost is that of its best v. The whole strip's cost per shift is the
/// bands' per-pixel costs weighed by their rows (with one band: the best v's), so an image moved vertically
/// by up to V rows (the camera pitched or rolled) matches as if level.
ShiftedDifference stripDifferenceVertical(const Strip& strip, int bands, int vertical, const uint8_t* query,
                                          const uint8_t* keyframe, bool subpixel)
{
  const int m = strip.max_shift, shifts = 2 * m + 1, rows = strip.height - strip.first_row;
  const float columns = static_cast<float>(strip.columns());
  float whole[256] = {};
  float best_sum = 0.0f;
  for (int b = 0; b < bands; ++b)
  {
    const int top = strip.first_row + rows * b / bands, bottom = strip.first_row + rows * (b + 1) / bands;
    float band[256];
    std::fill_n(band, 256, std::numeric_limits<float>::infinity());
    for (int v = -vertical; v <= vertical; ++v)
    {
      const int first = std::max(top, strip.first_row + v), last = std::min(bottom, strip.height + v);
      if (2 * (last - first) < bottom - top)
        continue;  // under half the band's rows have a counterpart: too few to weigh against the level rows
      const Strip part{ strip.width, 0, last - first, m };
      uint32_t sad[256];
      std::fill_n(sad, shifts, 0u);
      part.sads(query + static_cast<size_t>(first) * strip.width, keyframe + static_cast<size_t>(first - v) * strip.width,
                -m, shifts, sad);
      const float pixels = static_cast<float>(last - first) * columns;
      for (int i = 0; i < shifts; ++i)
        band[i] = std::min(band[i], static_cast<float>(sad[i]) / pixels);
    }
    const float weight = static_cast<float>(bottom - top) / static_cast<float>(rows);
    float least = band[0];
    for (int i = 0; i < shifts; ++i)
    {
      least = std::min(least, band[i]);
      whole[i] += weight * band[i];
    }
    best_sum += weight * least;
  }
  ShiftedDifference d = pickBestShift(whole, m, 1.0f, subpixel);  // the whole strip's shift
  if (bands > 1)
    d.cost = best_sum;
  return d;
}

/// Step 2 for one keyframe: the strip at its best shift, or with `bands` > 1 the compared rows in that many
/// horizontal bands, each at its own best shift, or with `vertical` > 0 also at its best vertical offset
/// (ImageDifference). `next`: the keyframe compared after this one.
ShiftedDifference stripDifference(const Strip& strip, int bands, int vertical, const uint8_t* query,
                                  const uint8_t* keyframe, int compared_pixels, bool subpixel,
                                  const uint8_t* next = nullptr)
{
  if (vertical > 0)
    return stripDifferenceVertical(strip, bands, vertical, query, keyframe, subpixel);
  const int m = strip.max_shift, shifts = 2 * m + 1, rows = strip.height - strip.first_row;
  if (bands == 1)
  {
    uint32_t sad[256];
    strip.sads(query, keyframe, -m, shifts, sad, next);
    return pickBestShift(sad, m, static_cast<float>(compared_pixels), subpixel);
  }
  uint32_t whole[256] = {};
  uint64_t best_sum = 0;
  for (int b = 0; b < bands; ++b)
  {
    const Strip band{ strip.width, strip.first_row + rows * b / bands, strip.first_row + rows * (b + 1) / bands, m };
    uint32_t sad[256];
    std::fill_n(sad, shifts, 0u);  // (written by sads; set so that no compiler sees a read of unset bytes)
    band.sads(query, keyframe, -m, shifts, sad, next);
    uint32_t least = sad[0];
    for (int i = 0; i < shifts; ++i)
    {
      least = std::min(least, sad[i]);
      whole[i] += sad[i];
    }
    best_sum += least;
  }
  ShiftedDifference d = pickBestShift(whole, m, static_cast<float>(compared_pixels), subpixel);  // the whole strip's
  d.cost = static_cast<float>(best_sum) / static_cast<float>(compared_pixels);
  return d;
}

}  // namespace

ImageDifference::ImageDifference(int width, int height, int first_row, int max_shift_px, bool subpixel, int bands,
                                 int max_vertical_shift_px)
  : width_(width), height_(height), first_row_(first_row), max_shift_px_(max_shift_px), subpixel_(subpixel),
    bands_(bands), max_vertical_shift_px_(max_vertical_shift_px)
{
  if (width <= 0 || height <= 0 || first_row < 0 || first_row >= height)
    throw std::invalid_argument("ImageDifference: need width, height > 0 and 0 <= first_row < height");
  if (bands < 1 || bands > height - first_row)
    throw std::invalid_argument("ImageDifference: bands must be in [1, compared rows]");
  if (max_shift_px < 0 || max_shift_px > 127 || width - 2 * max_shift_px < 1)
    throw std::invalid_argument("ImageDifference: max_shift_px must be in [0, min(127, (width - 1) / 2)]");
  if (max_vertical_shift_px < 0 || 2 * max_vertical_shift_px >= height - first_row)
    throw std::invalid_argument("ImageDifference: max_vertical_shift_px must be below half the compared rows");
}

uint32_t ImageDifference::sadAtShift(const uint8_t* query, const uint8_t* keyframe, int shift_px) const
{
  uint32_t sum = 0;
  Strip{ width_, first_row_, height_, max_shift_px_ }.sads(query, keyframe, shift_px, 1, &sum);
  return sum;
}

ShiftedDifference ImageDifference::compare(const uint8_t* query, const uint8_t* keyframe) const
{
  return stripDifference(Strip{ width_, first_row_, height_, max_shift_px_ }, bands_, max_vertical_shift_px_, query,
                         keyframe, comparedPixels(), subpixel_);
}

namespace
{

/// compareMany's loop over keyframes [range.start, range.end), as a body for cv::parallel_for_.
class CompareManyBody : public cv::ParallelLoopBody
{
public:
  CompareManyBody(const Strip& strip, int bands, int vertical, int compared_pixels, bool subpixel,
                  const uint8_t* query, const uint8_t* keyframes, float* costs, float* shifts)
    : strip_(strip), bands_(bands), vertical_(vertical), compared_pixels_(compared_pixels), subpixel_(subpixel),
      query_(query),
      keyframes_(keyframes), costs_(costs), shifts_(shifts)
  {
  }

  void operator()(const cv::Range& range) const override
  {
    const size_t bytes = static_cast<size_t>(strip_.width) * strip_.height;
    for (int k = range.start; k < range.end; ++k)
    {
      const uint8_t* keyframe = keyframes_ + k * bytes;
      const ShiftedDifference d = stripDifference(strip_, bands_, vertical_, query_, keyframe, compared_pixels_,
                                                  subpixel_,
                                                  k + 1 < range.end ? keyframe + bytes : nullptr);
      costs_[k] = d.cost;
      shifts_[k] = d.shift_px;
    }
  }

private:
  Strip strip_;
  int bands_;
  int vertical_;
  int compared_pixels_;
  bool subpixel_;
  const uint8_t* query_;
  const uint8_t* keyframes_;
  float* costs_;
  float* shifts_;
};

}  // namespace

void ImageDifference::compareMany(const uint8_t* query, const uint8_t* keyframes, int count, float* costs,
                                  float* shifts, bool parallel) const
{
  const CompareManyBody body(Strip{ width_, first_row_, height_, max_shift_px_ }, bands_, max_vertical_shift_px_,
                             comparedPixels(), subpixel_,
                             query, keyframes, costs, shifts);
  // Below a few hundred keyframes the thread hand-over costs more than it saves.
  if (parallel && count >= 512)
    cv::parallel_for_(cv::Range(0, count), body, std::max(1.0, count / 256.0));
  else
    body(cv::Range(0, count));
}

void censusTransform(const uint8_t* image, int width, int height, uint8_t* codes)
{
  const auto at = [&](int y, int x) {
    y = std::min(std::max(y, 0), height - 1);
    x = std::min(std::max(x, 0), width - 1);
    return image[static_cast<size_t>(y) * width + x];
  };
  for (int y = 0; y < height; ++y)
  {
    for (int x = 0; x < width; ++x)
    {
      const uint8_t centre = at(y, x);
      uint8_t code = 0;
      int bit = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
        {
          if (dy == 0 && dx == 0)
            continue;
          if (at(y + dy, x + dx) < centre)
            code |= static_cast<uint8_t>(1u << bit);
          ++bit;
        }
      codes[static_cast<size_t>(y) * width + x] = code;
    }
  }
}

CensusDifference::CensusDifference(int width, int height, int first_row, int max_shift_px, bool subpixel)
  : geometry_(width, height, first_row, max_shift_px, subpixel)
{
}

ShiftedDifference CensusDifference::compare(const uint8_t* query, const uint8_t* keyframe) const
{
  const int m = geometry_.maxShift(), w = geometry_.width(), h = geometry_.height();
  const int strip = w - 2 * m;
  uint32_t cost[256];
  for (int i = 0; i <= 2 * m; ++i)
  {
    uint32_t sum = 0;
    for (int y = geometry_.firstRow(); y < h; ++y)
      sum += hammingBytes(query + static_cast<size_t>(y) * w + m, keyframe + static_cast<size_t>(y) * w + m - (i - m),
                          strip);
    cost[i] = sum;
  }
  return pickBestShift(cost, m, static_cast<float>(geometry_.comparedPixels()), geometry_.subpixel());
}

void halveImage(const uint8_t* image, int width, int height, uint8_t* half)
{
  const int half_width = width / 2, half_height = height / 2;
  for (int y = 0; y < half_height; ++y)
  {
    const uint8_t* top = image + static_cast<size_t>(2 * y) * width;
    const uint8_t* bottom = top + width;
    uint8_t* out = half + static_cast<size_t>(y) * half_width;
    for (int x = 0; x < half_width; ++x)
      out[x] = static_cast<uint8_t>((top[2 * x] + top[2 * x + 1] + bottom[2 * x] + bottom[2 * x + 1] + 2) / 4);
  }
}

void halveImages(const uint8_t* images, size_t count, int width, int height, uint8_t* halves)
{
  if (count == 0)
    return;
  if (width % 2 == 0 && height % 2 == 0 && count * height <= static_cast<size_t>(INT_MAX))
  {
    // For even sizes INTER_AREA at exactly half size is the rounded 2x2 mean, and no 2x2 block of the
    // stack straddles two images.
    const cv::Mat stack(static_cast<int>(count * height), width, CV_8UC1, const_cast<uint8_t*>(images));
    cv::Mat out(static_cast<int>(count * height / 2), width / 2, CV_8UC1, halves);
    cv::resize(stack, out, out.size(), 0.0, 0.0, cv::INTER_AREA);
    return;
  }
  const size_t bytes = static_cast<size_t>(width) * height, half_bytes = static_cast<size_t>(width / 2) * (height / 2);
  for (size_t i = 0; i < count; ++i)
    halveImage(images + i * bytes, width, height, halves + i * half_bytes);
}

float textureEnergy(const uint8_t* image, int width, int height, int first_row)
{
  if (first_row >= height)
    return 0.0f;
  uint64_t sum = 0;
  for (int y = first_row; y < height; ++y)
    for (int x = 0; x < width; ++x)
      sum += static_cast<uint64_t>(std::abs(static_cast<int>(image[static_cast<size_t>(y) * width + x]) - 128));
  return static_cast<float>(static_cast<double>(sum) / (static_cast<double>(height - first_row) * width));
}

}  // namespace along_route_localization
