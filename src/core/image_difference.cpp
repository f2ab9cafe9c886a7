#include "along_route_localization/image_difference.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include <opencv2/core.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
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
inline uint32_t sadBytes(const uint8_t* a, const uint8_t* b, int n)
{
  uint32_t sum = 0;
  int i = 0;
#if defined(__SSE2__)
  __m128i acc = _mm_setzero_si128();
  for (; i + 16 <= n; i += 16)
    acc = _mm_add_epi64(acc, _mm_sad_epu8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i)),
                                          _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i))));
  if (i + 8 <= n)
  {
    acc = _mm_add_epi64(acc, _mm_sad_epu8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(a + i)),
                                          _mm_loadl_epi64(reinterpret_cast<const __m128i*>(b + i))));
    i += 8;
  }
  sum = static_cast<uint32_t>(_mm_cvtsi128_si32(acc) + _mm_cvtsi128_si32(_mm_srli_si128(acc, 8)));
#endif
  for (; i < n; ++i)
    sum += static_cast<uint32_t>(std::abs(static_cast<int>(a[i]) - static_cast<int>(b[i])));
  return sum;
}

inline uint32_t hammingBytes(const uint8_t* a, const uint8_t* b, int n)
{
  uint32_t sum = 0;
  for (int i = 0; i < n; ++i)
    sum += static_cast<uint32_t>(__builtin_popcount(static_cast<unsigned>(a[i] ^ b[i])));
  return sum;
}

/// Picks the best of the 2m + 1 costs (ties go to the smallest |d|: with no evidence of a rotation,
/// report none) and refines the shift with the parabola through it and its neighbours.
ShiftedDifference pickBestShift(const uint32_t* cost, int max_shift_px, int compared_pixels, bool subpixel)
{
  const int shifts = 2 * max_shift_px + 1;
  int best = 0;
  for (int i = 1; i < shifts; ++i)
    if (cost[i] < cost[best] || (cost[i] == cost[best] && std::abs(i - max_shift_px) < std::abs(best - max_shift_px)))
      best = i;
  ShiftedDifference result;
  result.cost = static_cast<float>(cost[best]) / static_cast<float>(compared_pixels);
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

}  // namespace

ImageDifference::ImageDifference(int width, int height, int first_row, int max_shift_px, bool subpixel)
  : width_(width), height_(height), first_row_(first_row), max_shift_px_(max_shift_px), subpixel_(subpixel)
{
  if (width <= 0 || height <= 0 || first_row < 0 || first_row >= height)
    throw std::invalid_argument("ImageDifference: need width, height > 0 and 0 <= first_row < height");
  if (max_shift_px < 0 || max_shift_px > 127 || width - 2 * max_shift_px < 1)
    throw std::invalid_argument("ImageDifference: max_shift_px must be in [0, min(127, (width - 1) / 2)]");
}

uint32_t ImageDifference::sadAtShift(const uint8_t* query, const uint8_t* keyframe, int shift_px) const
{
  const int strip = width_ - 2 * max_shift_px_;
  uint32_t sum = 0;
  for (int y = first_row_; y < height_; ++y)
  {
    const uint8_t* q = query + static_cast<size_t>(y) * width_ + max_shift_px_;
    sum += sadBytes(q, keyframe + static_cast<size_t>(y) * width_ + max_shift_px_ - shift_px, strip);
  }
  return sum;
}

ShiftedDifference ImageDifference::compare(const uint8_t* query, const uint8_t* keyframe) const
{
  uint32_t sad[256];
  const int shifts = 2 * max_shift_px_ + 1;
  for (int i = 0; i < shifts; ++i)
    sad[i] = sadAtShift(query, keyframe, i - max_shift_px_);
  return pickBestShift(sad, max_shift_px_, comparedPixels(), subpixel_);
}

void ImageDifference::compareMany(const uint8_t* query, const uint8_t* keyframes, int count, float* costs,
                                  float* shifts, bool parallel) const
{
  const size_t bytes = static_cast<size_t>(width_) * height_;
  const auto run = [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k)
    {
      const ShiftedDifference d = compare(query, keyframes + k * bytes);
      costs[k] = d.cost;
      shifts[k] = d.shift_px;
    }
  };
  // Below a few hundred keyframes the thread hand-over costs more than it saves.
  if (parallel && count >= 512)
    cv::parallel_for_(cv::Range(0, count), run, std::max(1.0, count / 256.0));
  else
    run(cv::Range(0, count));
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
  return pickBestShift(cost, m, geometry_.comparedPixels(), geometry_.subpixel());
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
