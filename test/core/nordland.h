// Shared helpers for the core tests: the real Nordland frames (../shared/data/nordland).
// Frame number f is the file images-<10*f>.png (every 10th frame of the 1 fps release); summer and
// winter frames with the same number show the same place. Tests that need them call
// SKIP_WITHOUT_NORDLAND() first and are skipped with a message when the folder is missing.
#ifndef ALONG_ROUTE_LOCALIZATION_TEST_CORE_NORDLAND_H
#define ALONG_ROUTE_LOCALIZATION_TEST_CORE_NORDLAND_H

#include <sys/stat.h>

#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#ifndef ALONG_ROUTE_NORDLAND_DIR
#define ALONG_ROUTE_NORDLAND_DIR ""
#endif

namespace nordland
{

inline std::string dir()
{
  return ALONG_ROUTE_NORDLAND_DIR;
}

/// "summer" or "winter", frame number 1..1788.
inline std::string framePath(const std::string& season, int frame)
{
  char name[32];
  std::snprintf(name, sizeof(name), "images-%05d.png", 10 * frame);
  return dir() + "/" + season + "/" + name;
}

inline bool available()
{
  struct stat info;
  return !dir().empty() && stat(framePath("summer", 1000).c_str(), &info) == 0 &&
         stat(framePath("winter", 1000).c_str(), &info) == 0;
}

/// The raw 64x32 frame as BGR8 (what cv::imread returns); empty if it cannot be read.
inline cv::Mat loadFrame(const std::string& season, int frame)
{
  return cv::imread(framePath(season, frame), cv::IMREAD_COLOR);
}

/// Frames [first, first + count) of one season, raw BGR8.
inline std::vector<cv::Mat> loadFrames(const std::string& season, int first, int count)
{
  std::vector<cv::Mat> frames;
  frames.reserve(count);
  for (int f = first; f < first + count; ++f)
    frames.push_back(loadFrame(season, f));
  return frames;
}

}  // namespace nordland

/// Skips the current test, saying why, when the Nordland frames are not where CMake said.
#define SKIP_WITHOUT_NORDLAND()                                                                      \
  do                                                                                                 \
  {                                                                                                  \
    if (!nordland::available())                                                                      \
      GTEST_SKIP() << "Nordland frames not found in '" << nordland::dir()                            \
                   << "' (CMake cache variable ALONG_ROUTE_NORDLAND_DIR); skipping this test";       \
  } while (0)

#endif  // ALONG_ROUTE_LOCALIZATION_TEST_CORE_NORDLAND_H
