// Step 1 (preprocessing.h): input encodings, eq. 1 patch normalization, eq. 3 divisive normalization,
// the whole Preprocessor and its parameters. Expected numbers are worked out by hand in the comments
// or computed by an independent reference (cv::cvtColor, plain loops over cv::getGaussianKernel).
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "along_route_localization/preprocessing.h"

namespace arl = along_route_localization;
using arl::PixelFormat;
using arl::PreprocessingError;

namespace
{

int at8(const cv::Mat& image, int y, int x)
{
  return image.at<uint8_t>(y, x);
}

cv::Mat randomImage(int rows, int cols, int type, uint64_t seed)
{
  cv::Mat image(rows, cols, type);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return image;
}

int reflect101(int p, int n)
{
  if (p < 0)
    return -p;
  if (p >= n)
    return 2 * n - 2 - p;
  return p;
}

// Independent eq. 3: Gaussian weights from cv::getGaussianKernel, BORDER_REFLECT_101 done by hand,
// local std as sqrt(E_g[I^2] - mu_g^2). Returns the unrounded output level 128 + gain * s * I'.
cv::Mat referenceDivisive(const cv::Mat& input, int window, double strength, double gain)
{
  const cv::Mat kernel = cv::getGaussianKernel(window, -1, CV_64F);
  const int half = window / 2;
  cv::Mat out(input.size(), CV_64F);
  for (int y = 0; y < input.rows; ++y)
    for (int x = 0; x < input.cols; ++x)
    {
      double mean = 0.0, mean_sq = 0.0;
      for (int i = 0; i < window; ++i)
        for (int j = 0; j < window; ++j)
        {
          const double w = kernel.at<double>(i) * kernel.at<double>(j);
          const double v = at8(input, reflect101(y + i - half, input.rows), reflect101(x + j - half, input.cols));
          mean += w * v;
          mean_sq += w * v * v;
        }
      const double sigma = std::sqrt(std::max(0.0, mean_sq - mean * mean));
      const double normalized = (at8(input, y, x) - mean) / (1.0 + strength * sigma);
      out.at<double>(y, x) = 128.0 + gain * strength * normalized;
    }
  return out;
}

// Largest |actual - round(saturate(reference))| over the image.
double maxDeviation(const cv::Mat& actual, const cv::Mat& reference)
{
  double worst = 0.0;
  for (int y = 0; y < actual.rows; ++y)
    for (int x = 0; x < actual.cols; ++x)
    {
      const double expected = std::round(std::min(255.0, std::max(0.0, reference.at<double>(y, x))));
      worst = std::max(worst, std::abs(at8(actual, y, x) - expected));
    }
  return worst;
}

// 8 rows x 16 columns: columns 0..7 at 64, columns 8..15 at 192.
cv::Mat stepEdge()
{
  cv::Mat image(8, 16, CV_8UC1, cv::Scalar(64));
  image.colRange(8, 16).setTo(192);
  return image;
}

}  // namespace

// ---------------------------------------------------------------- encodings

TEST(PixelFormat, AcceptsTheDocumentedEncodings)
{
  const struct
  {
    const char* name;
    PixelFormat format;
  } cases[] = { { "mono8", PixelFormat::kMono8 },   { "8UC1", PixelFormat::kMono8 },
                { "mono16", PixelFormat::kMono16 }, { "16UC1", PixelFormat::kMono16 },
                { "bgr8", PixelFormat::kBgr8 },     { "rgb8", PixelFormat::kRgb8 },
                { "bgra8", PixelFormat::kBgra8 },   { "rgba8", PixelFormat::kRgba8 },
                { "32FC1", PixelFormat::kMono32F } };
  for (const auto& c : cases)
  {
    PixelFormat format = PixelFormat::kMono8;
    if (c.format == PixelFormat::kMono8)
      format = PixelFormat::kRgba8;  // so that "left alone" cannot pass by accident
    EXPECT_TRUE(arl::pixelFormatFromEncoding(c.name, &format)) << c.name;
    EXPECT_EQ(c.format, format) << c.name;
  }
}

TEST(PixelFormat, RejectsOtherEncodingsAndLeavesFormatAlone)
{
  for (const char* name : { "", "bayer_rggb8", "yuv422", "16SC1", "32FC3", "rgb16", "mono", "bgr" })
  {
    PixelFormat format = PixelFormat::kBgra8;
    EXPECT_FALSE(arl::pixelFormatFromEncoding(name, &format)) << name;
    EXPECT_EQ(PixelFormat::kBgra8, format) << name;
  }
  EXPECT_FALSE(arl::supportedEncodings().empty());
}

TEST(ToGray, Mono8IsCopiedUnchanged)
{
  const cv::Mat input = randomImage(5, 7, CV_8UC1, 1);
  cv::Mat gray;
  arl::toGray(input, PixelFormat::kMono8, gray);
  ASSERT_EQ(CV_8UC1, gray.type());
  ASSERT_EQ(input.size(), gray.size());
  EXPECT_EQ(0, cv::norm(input, gray, cv::NORM_INF));
}

TEST(ToGray, Mono16IsScaledBy1Over257)
{
  // 257 * k -> k exactly; 257 * k + 50 -> k + 0.19 -> k whether rounded or truncated.
  const uint16_t values[] = { 0, 257, 257 * 100, 257 * 100 + 50, 257 * 200, 65535 };
  const int expected[] = { 0, 1, 100, 100, 200, 255 };
  cv::Mat input(1, 6, CV_16UC1);
  for (int i = 0; i < 6; ++i)
    input.at<uint16_t>(0, i) = values[i];
  cv::Mat gray;
  arl::toGray(input, PixelFormat::kMono16, gray);
  ASSERT_EQ(CV_8UC1, gray.type());
  for (int i = 0; i < 6; ++i)
    EXPECT_EQ(expected[i], at8(gray, 0, i)) << "input " << values[i];
}

TEST(ToGray, Bgr8AndRgb8UseTheirOwnChannelOrder)
{
  // Three pixels: bytes (255,0,0), (0,255,0), (0,0,255). Luma 0.299 R + 0.587 G + 0.114 B:
  // as bgr8 the first is pure blue -> 0.114 * 255 = 29.07 -> 29, the last pure red -> 76.2 -> 76;
  // as rgb8 the same bytes read the other way round. Green is 0.587 * 255 = 149.7 -> 150 in both.
  cv::Mat input(1, 3, CV_8UC3);
  input.at<cv::Vec3b>(0, 0) = cv::Vec3b(255, 0, 0);
  input.at<cv::Vec3b>(0, 1) = cv::Vec3b(0, 255, 0);
  input.at<cv::Vec3b>(0, 2) = cv::Vec3b(0, 0, 255);
  cv::Mat bgr_gray, rgb_gray;
  arl::toGray(input, PixelFormat::kBgr8, bgr_gray);
  arl::toGray(input, PixelFormat::kRgb8, rgb_gray);
  ASSERT_EQ(CV_8UC1, bgr_gray.type());
  ASSERT_EQ(CV_8UC1, rgb_gray.type());
  EXPECT_NEAR(29, at8(bgr_gray, 0, 0), 1);
  EXPECT_NEAR(150, at8(bgr_gray, 0, 1), 1);
  EXPECT_NEAR(76, at8(bgr_gray, 0, 2), 1);
  EXPECT_NEAR(76, at8(rgb_gray, 0, 0), 1);
  EXPECT_NEAR(150, at8(rgb_gray, 0, 1), 1);
  EXPECT_NEAR(29, at8(rgb_gray, 0, 2), 1);

  // And exactly what cv::cvtColor does on a random image.
  const cv::Mat random = randomImage(16, 20, CV_8UC3, 2);
  cv::Mat expected;
  arl::toGray(random, PixelFormat::kBgr8, bgr_gray);
  cv::cvtColor(random, expected, cv::COLOR_BGR2GRAY);
  EXPECT_LE(cv::norm(expected, bgr_gray, cv::NORM_INF), 1);
  arl::toGray(random, PixelFormat::kRgb8, rgb_gray);
  cv::cvtColor(random, expected, cv::COLOR_RGB2GRAY);
  EXPECT_LE(cv::norm(expected, rgb_gray, cv::NORM_INF), 1);
}

TEST(ToGray, Bgra8AndRgba8IgnoreAlpha)
{
  cv::Mat input(1, 2, CV_8UC4);
  input.at<cv::Vec4b>(0, 0) = cv::Vec4b(255, 0, 0, 0);    // blue (bgra) / red (rgba), alpha 0
  input.at<cv::Vec4b>(0, 1) = cv::Vec4b(255, 0, 0, 255);  // same colour, alpha 255
  cv::Mat bgra_gray, rgba_gray;
  arl::toGray(input, PixelFormat::kBgra8, bgra_gray);
  arl::toGray(input, PixelFormat::kRgba8, rgba_gray);
  ASSERT_EQ(CV_8UC1, bgra_gray.type());
  EXPECT_NEAR(29, at8(bgra_gray, 0, 0), 1);  // 0.114 * 255
  EXPECT_EQ(at8(bgra_gray, 0, 0), at8(bgra_gray, 0, 1));
  EXPECT_NEAR(76, at8(rgba_gray, 0, 0), 1);  // 0.299 * 255
  EXPECT_EQ(at8(rgba_gray, 0, 0), at8(rgba_gray, 0, 1));

  const cv::Mat random = randomImage(9, 11, CV_8UC4, 3);
  cv::Mat expected;
  arl::toGray(random, PixelFormat::kBgra8, bgra_gray);
  cv::cvtColor(random, expected, cv::COLOR_BGRA2GRAY);
  EXPECT_LE(cv::norm(expected, bgra_gray, cv::NORM_INF), 1);
  arl::toGray(random, PixelFormat::kRgba8, rgba_gray);
  cv::cvtColor(random, expected, cv::COLOR_RGBA2GRAY);
  EXPECT_LE(cv::norm(expected, rgba_gray, cv::NORM_INF), 1);
}

TEST(ToGray, FloatIsScaledBy255)
{
  // (k + 0.25) / 255 -> k + 0.25 -> k (rounded or truncated); 1 -> 255; beyond [0, 1] saturates.
  const float values[] = { 0.0f, (10 + 0.25f) / 255.0f, (100 + 0.25f) / 255.0f, 1.0f, 1.5f, -0.5f };
  const int expected[] = { 0, 10, 100, 255, 255, 0 };
  cv::Mat input(1, 6, CV_32FC1);
  for (int i = 0; i < 6; ++i)
    input.at<float>(0, i) = values[i];
  cv::Mat gray;
  arl::toGray(input, PixelFormat::kMono32F, gray);
  ASSERT_EQ(CV_8UC1, gray.type());
  for (int i = 0; i < 6; ++i)
    EXPECT_EQ(expected[i], at8(gray, 0, i)) << "input " << values[i];
}

TEST(ToGray, FloatOutsideZeroToOneIsNamed)
{
  cv::Mat input(2, 3, CV_32FC1, cv::Scalar(0.5));
  std::string sentence = "untouched";
  EXPECT_FALSE(arl::floatOutsideUnitRange(input, &sentence));
  input.at<float>(0, 0) = 0.0f;
  input.at<float>(1, 2) = 1.0f;
  EXPECT_FALSE(arl::floatOutsideUnitRange(input, &sentence));  // the ends are inside
  EXPECT_EQ("untouched", sentence);
  input.at<float>(1, 1) = 1.25f;
  ASSERT_TRUE(arl::floatOutsideUnitRange(input, &sentence));
  EXPECT_EQ("32FC1 values from 0 to 1.25, outside the [0, 1] read as intensity: clipped", sentence);
  input.at<float>(0, 1) = -3.5f;
  ASSERT_TRUE(arl::floatOutsideUnitRange(input, &sentence));
  EXPECT_EQ("32FC1 values from -3.5 to 1.25, outside the [0, 1] read as intensity: clipped", sentence);
  EXPECT_TRUE(arl::floatOutsideUnitRange(input, nullptr));
  // Other types are never float intensity.
  EXPECT_FALSE(arl::floatOutsideUnitRange(cv::Mat(2, 2, CV_8UC1, cv::Scalar(200)), &sentence));
}

TEST(Preprocessor, InputSmallerThanTheOutputIsNamedAndComesOutWithoutDetail)
{
  arl::PreprocessingParams params;  // 64 x 32 output
  std::string sentence = "untouched";
  EXPECT_FALSE(arl::inputSmallerThanOutput(64, 32, params, &sentence));
  EXPECT_FALSE(arl::inputSmallerThanOutput(640, 480, params, &sentence));
  EXPECT_FALSE(arl::inputSmallerThanOutput(0, 0, params, &sentence));  // empty: toGray's error
  EXPECT_EQ("untouched", sentence);
  EXPECT_TRUE(arl::inputSmallerThanOutput(63, 480, params, nullptr));  // one side is enough
  EXPECT_TRUE(arl::inputSmallerThanOutput(640, 31, params, nullptr));
  ASSERT_TRUE(arl::inputSmallerThanOutput(1, 1, params, &sentence));
  EXPECT_EQ("smaller than the 64x32 output: enlarged, it holds less detail than the output has room for (a "
            "camera mode of at least 64x32 px, or smaller output_width / output_height)",
            sentence);
  // What a 1 x 1 frame becomes: one gray level everywhere, nothing to match on.
  arl::Preprocessor preprocessor(params);
  cv::Mat output;
  preprocessor.process(cv::Mat(1, 1, CV_8UC1, cv::Scalar(200)), PixelFormat::kMono8, output);
  ASSERT_EQ(cv::Size(64, 32), output.size());
  double low = 0.0, high = 0.0;
  cv::minMaxLoc(output, &low, &high);
  EXPECT_EQ(low, high);
}

TEST(ToGray, FloatNanAndInfAreRejected)
{
  cv::Mat input(4, 4, CV_32FC1, cv::Scalar(0.5));
  cv::Mat gray;
  input.at<float>(2, 3) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(arl::toGray(input, PixelFormat::kMono32F, gray), PreprocessingError);
  input.at<float>(2, 3) = std::numeric_limits<float>::infinity();
  EXPECT_THROW(arl::toGray(input, PixelFormat::kMono32F, gray), PreprocessingError);
}

TEST(ToGray, TypeThatDoesNotMatchTheFormatThrows)
{
  cv::Mat gray;
  const cv::Mat mono8(4, 4, CV_8UC1, cv::Scalar(1));
  const cv::Mat color3(4, 4, CV_8UC3, cv::Scalar(1, 2, 3));
  const cv::Mat color4(4, 4, CV_8UC4, cv::Scalar(1, 2, 3, 4));
  const cv::Mat mono16(4, 4, CV_16UC1, cv::Scalar(1));
  EXPECT_THROW(arl::toGray(color3, PixelFormat::kMono8, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(mono16, PixelFormat::kMono8, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(mono8, PixelFormat::kMono16, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(mono8, PixelFormat::kBgr8, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(color4, PixelFormat::kRgb8, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(color3, PixelFormat::kBgra8, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(mono8, PixelFormat::kRgba8, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(mono8, PixelFormat::kMono32F, gray), PreprocessingError);
  EXPECT_THROW(arl::toGray(cv::Mat(), PixelFormat::kMono8, gray), PreprocessingError);
}

// ---------------------------------------------------------------- eq. 1

TEST(PatchNormalize, KnownPatchFlatPatchAndLowStdPatch)
{
  // 8 x 24 image, three 8x8 patches.
  // Patch 0: rows 0-1 = 90, rows 2-3 = 110, rows 4-5 = 130, rows 6-7 = 150 (16 pixels each).
  //   mean = 120; population variance = (30^2 + 10^2 + 10^2 + 30^2) / 4 = 500, std = 22.3607.
  //   90 -> 128 + 32 * (-30 / 22.3607) = 128 - 42.93 = 85.07 -> 85
  //   110 -> 128 - 14.31 = 113.69 -> 114;  130 -> 142.31 -> 142;  150 -> 170.93 -> 171.
  // Patch 1: flat 77 -> std 0 -> 128.
  // Patch 2: checkerboard of 100/101 -> std 0.5 < min_std 2 -> 128.
  cv::Mat image(8, 24, CV_8UC1);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 24; ++x)
    {
      if (x < 8)
        image.at<uint8_t>(y, x) = static_cast<uint8_t>(90 + 20 * (y / 2));
      else if (x < 16)
        image.at<uint8_t>(y, x) = 77;
      else
        image.at<uint8_t>(y, x) = static_cast<uint8_t>(100 + (x + y) % 2);
    }
  cv::Mat gain32 = image.clone();
  arl::patchNormalize(gain32, 8, 2.0, 32.0);
  const int expected_rows[4] = { 85, 114, 142, 171 };
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 24; ++x)
    {
      const int expected = x < 8 ? expected_rows[y / 2] : 128;
      EXPECT_EQ(expected, at8(gain32, y, x)) << "pixel (" << y << ", " << x << ")";
    }

  // Gain 16: 90 -> 128 - 21.47 = 106.53 -> 107; 150 -> 149.47 -> 149.
  cv::Mat gain16 = image.clone();
  arl::patchNormalize(gain16, 8, 2.0, 16.0);
  EXPECT_EQ(107, at8(gain16, 0, 0));
  EXPECT_EQ(149, at8(gain16, 7, 7));
  EXPECT_EQ(128, at8(gain16, 3, 12));
}

TEST(PatchNormalize, MinStdDecidesWhetherAPatchIsTexture)
{
  // Checkerboard 0/6: mean 3, population std 3. With min_std 2 it is texture:
  // 0 -> 128 + 32 * (-1) = 96, 6 -> 160. With min_std 4 it is flat -> 128.
  cv::Mat image(8, 8, CV_8UC1);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
      image.at<uint8_t>(y, x) = static_cast<uint8_t>(6 * ((x + y) % 2));
  cv::Mat textured = image.clone();
  arl::patchNormalize(textured, 8, 2.0, 32.0);
  EXPECT_EQ(96, at8(textured, 0, 0));
  EXPECT_EQ(160, at8(textured, 0, 1));
  cv::Mat flat = image.clone();
  arl::patchNormalize(flat, 8, 4.0, 32.0);
  EXPECT_EQ(0, cv::countNonZero(flat != 128));
}

TEST(PatchNormalize, SaturatesAtTheByteRange)
{
  // One bright pixel among 63 zeros: mean 255/64 = 3.984, std = sqrt(255^2/64 - 3.984^2) = 31.62.
  // Bright pixel z = (255 - 3.984) / 31.62 = 7.94 -> 128 + 254 -> saturates at 255;
  // the others: z = -0.126 -> 128 - 4.03 = 123.97 -> 124.
  cv::Mat image(8, 8, CV_8UC1, cv::Scalar(0));
  image.at<uint8_t>(3, 4) = 255;
  arl::patchNormalize(image, 8, 2.0, 32.0);
  EXPECT_EQ(255, at8(image, 3, 4));
  EXPECT_EQ(124, at8(image, 0, 0));
}

// ---------------------------------------------------------------- eq. 3

TEST(DivisiveNormalize, ConstantImageBecomes128)
{
  // mu_g = I and sigma_g = 0 everywhere, so I' = 0 -> 128, whatever the constant.
  for (int value : { 0, 128, 37, 255 })
  {
    const cv::Mat input(16, 24, CV_8UC1, cv::Scalar(value));
    cv::Mat output;
    arl::divisiveNormalize(input, output, 7, 0.1, 32.0);
    ASSERT_EQ(CV_8UC1, output.type());
    ASSERT_EQ(input.size(), output.size());
    EXPECT_EQ(0, cv::countNonZero(output != 128)) << "constant " << value;
  }
}

TEST(DivisiveNormalize, StepEdgeMatchesIndependentReference)
{
  // Window 7: cv::getGaussianKernel(7) = [1, 3.5, 7, 9, 7, 3.5, 1] / 32.
  // Column 7 (last dark column): window columns 4..7 dark (weight 20.5/32 = 0.640625), 8..10 bright
  // (0.359375). mu = 64 * 0.640625 + 192 * 0.359375 = 110; E[I^2] = 4096 * 0.640625 + 36864 * 0.359375
  // = 15872; sigma = sqrt(15872 - 110^2) = 61.42. I' = (64 - 110) / (1 + 0.1 * 61.42) = -6.441;
  // byte = 128 + 32 * 0.1 * (-6.441) = 107.39 -> 107. By symmetry column 8 -> 148.61 -> 149.
  // Columns 0..4 and 11..15 see one level only -> 128.
  const cv::Mat input = stepEdge();
  cv::Mat output;
  arl::divisiveNormalize(input, output, 7, 0.1, 32.0);
  ASSERT_EQ(CV_8UC1, output.type());
  ASSERT_EQ(input.size(), output.size());
  const cv::Mat reference = referenceDivisive(input, 7, 0.1, 32.0);
  EXPECT_NEAR(107.389, reference.at<double>(0, 7), 1e-3);  // the reference agrees with the hand value
  EXPECT_LE(maxDeviation(output, reference), 1.0);
  for (int y = 0; y < 8; ++y)
  {
    EXPECT_NEAR(107, at8(output, y, 7), 1);
    EXPECT_NEAR(149, at8(output, y, 8), 1);
    for (int x : { 0, 1, 2, 3, 4, 11, 12, 13, 14, 15 })
      EXPECT_EQ(128, at8(output, y, x)) << "column " << x;
  }
}

TEST(DivisiveNormalize, StepEdgeIsAntisymmetric)
{
  // I(15 - x) = 256 - I(x) with mirrored (reflect-101) borders, so mu(15 - x) = 256 - mu(x), sigma is
  // equal and I'(15 - x) = -I'(x): byte(15 - x) - 128 = -(byte(x) - 128) up to rounding.
  // Dark side below 128, bright side above.
  cv::Mat output;
  arl::divisiveNormalize(stepEdge(), output, 7, 0.1, 32.0);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
    {
      EXPECT_NEAR(at8(output, y, x) - 128, -(at8(output, y, 15 - x) - 128), 1) << "column " << x;
      if (x >= 5)
      {
        EXPECT_LT(at8(output, y, x), 128) << "column " << x;
        EXPECT_GT(at8(output, y, 15 - x), 128) << "column " << 15 - x;
      }
    }
}

TEST(DivisiveNormalize, StrengthScalesTheResponse)
{
  // byte - 128 = gain * s * (I - mu) / (1 + s * sigma), increasing in s. At column 7 (reference):
  // s = 0.02 -> 114.79, s = 0.1 -> 107.39, s = 0.5 -> 104.79.
  const cv::Mat input = stepEdge();
  const double strengths[] = { 0.02, 0.1, 0.5 };
  const double expected_col7[] = { 114.788, 107.389, 104.788 };
  int previous_deviation = -1;
  for (int i = 0; i < 3; ++i)
  {
    cv::Mat output;
    arl::divisiveNormalize(input, output, 7, strengths[i], 32.0);
    const cv::Mat reference = referenceDivisive(input, 7, strengths[i], 32.0);
    EXPECT_NEAR(expected_col7[i], reference.at<double>(0, 7), 1e-3);
    EXPECT_LE(maxDeviation(output, reference), 1.0) << "s = " << strengths[i];
    const int deviation = 128 - at8(output, 0, 7);
    EXPECT_GT(deviation, previous_deviation) << "s = " << strengths[i];
    previous_deviation = deviation;
  }
}

TEST(DivisiveNormalize, RandomImageMatchesIndependentReference)
{
  const cv::Mat input = randomImage(32, 64, CV_8UC1, 4);
  for (int window : { 3, 7, 9 })
  {
    cv::Mat output;
    arl::divisiveNormalize(input, output, window, 0.1, 32.0);
    EXPECT_LE(maxDeviation(output, referenceDivisive(input, window, 0.1, 32.0)), 1.0) << "window " << window;
  }
}

// ---------------------------------------------------------------- Preprocessor

TEST(PreprocessingParams, DefaultsAreValidAndSkyRowsRound)
{
  arl::PreprocessingParams params;
  EXPECT_EQ("", params.validate());
  EXPECT_EQ(64, params.output_width);
  EXPECT_EQ(32, params.output_height);
  EXPECT_EQ(0, params.skyRows());
  params.sky_fraction = 0.25;  // 0.25 * 32 = 8
  EXPECT_EQ(8, params.skyRows());
  params.sky_fraction = 0.1;  // 3.2 -> 3
  EXPECT_EQ(3, params.skyRows());
  params.sky_fraction = 0.3;  // 9.6 -> 10
  EXPECT_EQ(10, params.skyRows());
}

TEST(PreprocessingParams, InvalidValuesAreNamedAndRejected)
{
  std::vector<arl::PreprocessingParams> invalid(8);
  invalid[0].output_width = 0;
  invalid[1].output_height = -4;
  invalid[2].normalization = arl::NormalizationMethod::kPatch;
  invalid[2].patch_size = 0;
  invalid[3].normalization = arl::NormalizationMethod::kPatch;
  invalid[3].patch_size = 7;  // 64 x 32 is not tiled by 7 x 7 patches (eq. 1)
  invalid[4].normalization = arl::NormalizationMethod::kDivisive;
  invalid[4].filter_window = 6;  // must be odd
  invalid[5].sky_fraction = 1.0;  // [0, 1)
  invalid[6].sky_fraction = -0.1;
  invalid[7].normalization = arl::NormalizationMethod::kDivisive;
  invalid[7].normalization_strength = -0.1;
  for (size_t i = 0; i < invalid.size(); ++i)
  {
    EXPECT_NE("", invalid[i].validate()) << "case " << i;
    arl::Preprocessor preprocessor;
    EXPECT_THROW(preprocessor.setParams(invalid[i]), PreprocessingError) << "case " << i;
  }
}

TEST(PreprocessingParams, EqualWhenTheyMakeTheSameBytes)
{
  // Fields the normalization does not read do not make two sets differ; the fields it reads do.
  // Checked on the bytes: a textured frame preprocessed with each set.
  cv::Mat frame(96, 128, CV_8UC1);
  cv::randu(frame, 0, 256);
  const auto bytes = [&frame](const arl::PreprocessingParams& params) {
    cv::Mat out;
    arl::Preprocessor(params).process(frame, arl::PixelFormat::kMono8, out);
    return std::vector<uint8_t>(out.begin<uint8_t>(), out.end<uint8_t>());
  };
  for (const auto method : { arl::NormalizationMethod::kDivisive, arl::NormalizationMethod::kPatch,
                             arl::NormalizationMethod::kNone })
  {
    arl::PreprocessingParams a;
    a.normalization = method;
    arl::PreprocessingParams patch = a, divisive = a, gain = a;
    patch.patch_size = 4;
    patch.min_patch_std = 7.0;
    divisive.filter_window = 11;
    divisive.normalization_strength = 0.3;
    gain.output_gain = 20.0;
    for (const arl::PreprocessingParams* b : { &patch, &divisive, &gain })
      EXPECT_EQ(*b == a, bytes(*b) == bytes(a)) << arl::toString(method) << ": " << b->serialize();
  }
}

TEST(PreprocessingParams, SerializeParseRoundTrip)
{
  arl::PreprocessingParams params;
  params.output_width = 80;
  params.output_height = 40;
  params.normalization = arl::NormalizationMethod::kDivisive;
  params.patch_size = 10;
  params.min_patch_std = 3.5;
  params.filter_window = 9;
  params.normalization_strength = 0.25;
  params.output_gain = 20.0;
  params.sky_fraction = 0.125;
  ASSERT_EQ("", params.validate());
  const std::string text = params.serialize();
  EXPECT_EQ(std::string::npos, text.find('\n'));

  arl::PreprocessingParams parsed;
  std::string error;
  ASSERT_TRUE(arl::PreprocessingParams::parse(text, &parsed, &error)) << error;
  EXPECT_TRUE(parsed == params) << text << " -> " << parsed.serialize();
  EXPECT_EQ(text, parsed.serialize());
  EXPECT_NE(params, arl::PreprocessingParams());

  const arl::PreprocessingParams defaults;
  ASSERT_TRUE(arl::PreprocessingParams::parse(defaults.serialize(), &parsed, &error)) << error;
  EXPECT_TRUE(parsed == defaults);
}

TEST(PreprocessingParams, ParseRejectsMalformedAndInvalidText)
{
  const std::string good = arl::PreprocessingParams().serialize();
  const size_t width_pos = good.find("output_width=");
  ASSERT_NE(std::string::npos, width_pos) << good;
  const size_t width_end = good.find(';', width_pos);
  std::string bad_number = good;
  bad_number.replace(width_pos, width_end == std::string::npos ? std::string::npos : width_end - width_pos,
                     "output_width=abc");
  std::string invalid_value = good;
  invalid_value.replace(width_pos, width_end == std::string::npos ? std::string::npos : width_end - width_pos,
                        "output_width=-64");

  for (const std::string& text : { std::string("this is not a parameter list"), bad_number, invalid_value })
  {
    arl::PreprocessingParams parsed;
    std::string error;
    EXPECT_FALSE(arl::PreprocessingParams::parse(text, &parsed, &error)) << text;
    EXPECT_FALSE(error.empty()) << text;
  }
}

TEST(PreprocessingParams, NormalizationNamesRoundTrip)
{
  for (auto method : { arl::NormalizationMethod::kNone, arl::NormalizationMethod::kPatch,
                       arl::NormalizationMethod::kDivisive })
  {
    arl::NormalizationMethod parsed = method == arl::NormalizationMethod::kNone ?
                                          arl::NormalizationMethod::kPatch :
                                          arl::NormalizationMethod::kNone;
    EXPECT_TRUE(arl::normalizationFromString(arl::toString(method), &parsed)) << arl::toString(method);
    EXPECT_EQ(method, parsed);
  }
  arl::NormalizationMethod parsed;
  EXPECT_FALSE(arl::normalizationFromString("histogram", &parsed));
}

TEST(Preprocessor, OutputSizeTypeAndSkyRows)
{
  arl::PreprocessingParams params;
  params.sky_fraction = 0.25;  // 8 of 32 rows
  arl::Preprocessor preprocessor(params);
  const cv::Mat input = randomImage(480, 640, CV_8UC3, 5);
  cv::Mat output;
  preprocessor.process(input, PixelFormat::kBgr8, output);
  ASSERT_EQ(32, output.rows);
  ASSERT_EQ(64, output.cols);
  ASSERT_EQ(CV_8UC1, output.type());
  EXPECT_EQ(0, cv::countNonZero(output.rowRange(0, 8)));
  // Random texture below the sky: rows 8..31 are not blank.
  for (int y = 8; y < 32; ++y)
    EXPECT_GT(cv::countNonZero(output.row(y)), 32) << "row " << y;

  params.output_width = 48;
  params.output_height = 24;
  params.sky_fraction = 0.0;
  preprocessor.setParams(params);
  preprocessor.process(input, PixelFormat::kBgr8, output);
  EXPECT_EQ(24, output.rows);
  EXPECT_EQ(48, output.cols);
}

TEST(Preprocessor, WritesInPlaceIntoPreallocatedOutput)
{
  arl::Preprocessor preprocessor;
  const cv::Mat input = randomImage(120, 160, CV_8UC3, 6);
  cv::Mat expected;
  preprocessor.process(input, PixelFormat::kRgb8, expected);

  // Like a cv::Mat wrapped around an outgoing message buffer.
  std::vector<uint8_t> buffer(64 * 32, 7);
  cv::Mat output(32, 64, CV_8UC1, buffer.data());
  preprocessor.process(input, PixelFormat::kRgb8, output);
  EXPECT_EQ(buffer.data(), output.data);
  const cv::Mat wrapped(32, 64, CV_8UC1, buffer.data());
  EXPECT_EQ(0, cv::norm(expected, wrapped, cv::NORM_INF));

  cv::Mat owned(32, 64, CV_8UC1, cv::Scalar(3));
  const uint8_t* before = owned.data;
  preprocessor.process(input, PixelFormat::kRgb8, owned);
  EXPECT_EQ(before, owned.data);
  EXPECT_EQ(0, cv::norm(expected, owned, cv::NORM_INF));
}

TEST(Preprocessor, AMono8InputIsNotWrittenByTheNextFrame)
{
  // A mono8 frame is read in place from the caller's buffer (a message's, freed after the callback). A
  // colour frame of the same size that follows must be converted into the preprocessor's own scratch,
  // not into that buffer (it did: the nodelet manager died of the heap corruption).
  arl::Preprocessor preprocessor;
  std::vector<uint8_t> message(120 * 160);
  for (size_t i = 0; i < message.size(); ++i)
    message[i] = static_cast<uint8_t>((i * 37) % 251);
  const std::vector<uint8_t> sent = message;
  cv::Mat output;
  preprocessor.process(cv::Mat(120, 160, CV_8UC1, message.data()), PixelFormat::kMono8, output);

  const cv::Mat colour = randomImage(120, 160, CV_8UC3, 11);
  cv::Mat expected;
  arl::Preprocessor(arl::PreprocessingParams()).process(colour, PixelFormat::kBgr8, expected);
  preprocessor.process(colour, PixelFormat::kBgr8, output);
  EXPECT_TRUE(message == sent) << "the previous mono8 frame's buffer was overwritten";
  EXPECT_EQ(0, cv::norm(expected, output, cv::NORM_INF));
}

TEST(Preprocessor, NoNormalizationAtOutputSizeIsPlainGray)
{
  // Input already 64 x 32: resizing is the identity, so the output is cvtColor's gray image.
  arl::PreprocessingParams params;
  params.normalization = arl::NormalizationMethod::kNone;
  arl::Preprocessor preprocessor(params);
  const cv::Mat input = randomImage(32, 64, CV_8UC3, 7);
  cv::Mat output, expected;
  preprocessor.process(input, PixelFormat::kBgr8, output);
  cv::cvtColor(input, expected, cv::COLOR_BGR2GRAY);
  EXPECT_LE(cv::norm(expected, output, cv::NORM_INF), 1);
}

TEST(Preprocessor, PatchNormalizationMatchesPlainLoopReference)
{
  // eq. 1 with the default patch parameters (8x8 patches, min std 2, gain 32) on a 64 x 32 mono8 input,
  // against eq. 1 written as plain loops.
  arl::PreprocessingParams params;
  params.normalization = arl::NormalizationMethod::kPatch;
  arl::Preprocessor preprocessor(params);
  cv::Mat input = randomImage(32, 64, CV_8UC1, 8);
  input(cv::Rect(8, 8, 8, 8)).setTo(90);  // one flat patch
  cv::Mat output;
  preprocessor.process(input, PixelFormat::kMono8, output);
  for (int py = 0; py < 32; py += 8)
    for (int px = 0; px < 64; px += 8)
    {
      double sum = 0.0, sum_sq = 0.0;
      for (int y = py; y < py + 8; ++y)
        for (int x = px; x < px + 8; ++x)
        {
          sum += at8(input, y, x);
          sum_sq += at8(input, y, x) * at8(input, y, x);
        }
      const double mean = sum / 64.0;
      const double std_dev = std::sqrt(std::max(0.0, sum_sq / 64.0 - mean * mean));
      for (int y = py; y < py + 8; ++y)
        for (int x = px; x < px + 8; ++x)
        {
          const double expected =
              std_dev < 2.0 ? 128.0 :
                              std::min(255.0, std::max(0.0, 128.0 + 32.0 * (at8(input, y, x) - mean) / std_dev));
          EXPECT_NEAR(expected, at8(output, y, x), 0.51) << "pixel (" << y << ", " << x << ")";
        }
    }
}

TEST(Preprocessor, DivisiveNormalizationAtOutputSizeMatchesReference)
{
  arl::PreprocessingParams params;
  params.normalization = arl::NormalizationMethod::kDivisive;
  params.sky_fraction = 0.125;  // 4 rows
  arl::Preprocessor preprocessor(params);
  const cv::Mat input = randomImage(32, 64, CV_8UC1, 9);
  cv::Mat output;
  preprocessor.process(input, PixelFormat::kMono8, output);
  EXPECT_EQ(0, cv::countNonZero(output.rowRange(0, 4)));
  const cv::Mat reference = referenceDivisive(input, params.filter_window, params.normalization_strength,
                                              params.output_gain);
  EXPECT_LE(maxDeviation(output.rowRange(4, 32), reference.rowRange(4, 32)), 1.0);
}

TEST(Preprocessor, BadInputThrows)
{
  arl::Preprocessor preprocessor;
  cv::Mat output;
  EXPECT_THROW(preprocessor.process(cv::Mat(), PixelFormat::kMono8, output), PreprocessingError);
  EXPECT_THROW(preprocessor.process(cv::Mat(32, 64, CV_8UC1, cv::Scalar(0)), PixelFormat::kBgr8, output),
               PreprocessingError);
  cv::Mat nan_image(32, 64, CV_32FC1, cv::Scalar(0.5));
  nan_image.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(preprocessor.process(nan_image, PixelFormat::kMono32F, output), PreprocessingError);
}
