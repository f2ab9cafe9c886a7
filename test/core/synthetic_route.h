// Shared helpers for tests on synthetic data: random textured frames and a route made of them. Used by
// the core tests and by the separately built ThreadSanitizer driver (test/sanitizers/tsan_parallel.cpp).
#ifndef ALONG_ROUTE_LOCALIZATION_TEST_CORE_SYNTHETIC_ROUTE_H
#define ALONG_ROUTE_LOCALIZATION_TEST_CORE_SYNTHETIC_ROUTE_H

#include <cstdint>
#include <memory>

#include <opencv2/core.hpp>

#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"

namespace synthetic
{

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
