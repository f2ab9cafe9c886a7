// Shared helpers for tests on synthetic data: random textured frames and a route made of them. Used by
// the core tests and by the separately built ThreadSanitizer driver (test/sanitizers/tsan_parallel.cpp).
#ifndef ALONG_ROUTE_LOCALIZATION_TEST_CORE_SYNTHETIC_ROUTE_H
#define ALONG_ROUTE_LOCALIZATION_TEST_CORE_SYNTHETIC_ROUTE_H

#include <algorithm>
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"

namespace synthetic
{

/// `count` uniform random bytes, reproducible from `seed` (std::mt19937).
inline std::vector<uint8_t> randomBytes(size_t count, uint32_t seed)
{
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<uint8_t> bytes(count);
  for (auto& b : bytes)
    b = static_cast<uint8_t>(byte(rng));
  return bytes;
}

/// query(x) = image(x - d), the edge replicated where x - d leaves the image (images_to_bag --shift-px).
inline std::vector<uint8_t> shiftedRight(const std::vector<uint8_t>& image, int width, int height, int d)
{
  std::vector<uint8_t> shifted(image.size());
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      shifted[y * width + x] = image[y * width + std::min(width - 1, std::max(0, x - d))];
  return shifted;
}

/// Uniform random bytes, reproducible from `seed`.
inline cv::Mat randomFrame(uint64_t seed, int rows = 32, int cols = 64)
{
  cv::Mat frame(rows, cols, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
  return frame;
}

/// A route of `count` random textured 64x32 keyframes: keyframe k is randomFrame(1000 + k), stamped k s.
inline std::shared_ptr<along_route_localization::RouteMap> syntheticMap(int count)
{
  auto map = std::make_shared<along_route_localization::RouteMap>(along_route_localization::PreprocessingParams());
  for (int k = 0; k < count; ++k)
    map->addKeyframe(randomFrame(1000 + k), 1000000000LL * k);
  return map;
}

}  // namespace synthetic

#endif  // ALONG_ROUTE_LOCALIZATION_TEST_CORE_SYNTHETIC_ROUTE_H
