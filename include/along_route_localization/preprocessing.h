// Step 1 of the method: camera image -> small, normalized 8-bit image (paper eq. 1 and eq. 3).
#ifndef ALONG_ROUTE_LOCALIZATION_PREPROCESSING_H
#define ALONG_ROUTE_LOCALIZATION_PREPROCESSING_H

#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace along_route_localization
{

/// Raised for input the preprocessor cannot turn into a frame (encoding, size, NaN, parameters).
class PreprocessingError : public std::invalid_argument
{
public:
  using std::invalid_argument::invalid_argument;
};

/// Pixel layouts accepted as input. Names follow the sensor_msgs/image_encodings strings.
enum class PixelFormat
{
  kMono8,
  kMono16,
  kBgr8,
  kRgb8,
  kBgra8,
  kRgba8,
  kMono32F  ///< float intensity in [0, 1]; NaN pixels are rejected
};

/// Parses "mono8", "8UC1", "mono16", "16UC1", "bgr8", "rgb8", "bgra8", "rgba8", "32FC1".
/// Returns false (and leaves *format alone) for anything else.
bool pixelFormatFromEncoding(const std::string& encoding, PixelFormat* format);

/// Human-readable list of the accepted encodings, for error messages.
std::string supportedEncodings();

enum class NormalizationMethod
{
  kNone,      ///< grayscale and resize only
  kPatch,     ///< SeqSLAM patch normalization, eq. 1
  kDivisive   ///< sliding-window divisive contrast normalization, eq. 3
};

std::string toString(NormalizationMethod method);
bool normalizationFromString(const std::string& name, NormalizationMethod* method);

/// Everything that decides how a frame becomes a preprocessed image. A map records these, and a
/// localizer refuses a map whose parameters differ from its own input's.
struct PreprocessingParams
{
  int output_width = 64;    ///< px
  int output_height = 32;   ///< px
  /// Which normalization: eq. 1 (patch) or eq. 3 (divisive, the default; doc/evaluation_history.md says
  /// why).
  NormalizationMethod normalization = NormalizationMethod::kDivisive;

  // eq. 1 (patch normalization)
  int patch_size = 8;             ///< px, square patches tiling the image
  double min_patch_std = 2.0;     ///< gray levels (0..255); flatter patches carry no texture and become 128

  // eq. 3 (divisive normalization)
  int filter_window = 7;               ///< px, odd side of the Gaussian window for local mean and std
  double normalization_strength = 0.1; ///< s in eq. 3, per gray level (0..255 scale)

  /// Bytes per unit of normalized intensity: byte = saturate(128 + output_gain * z), where z is the
  /// patch z-score (eq. 1) or s * I' (eq. 3), both dimensionless.
  double output_gain = 32.0;

  double sky_fraction = 0.0;  ///< share of the top rows set to 0 ("sky blackening"), in [0, 1)

  /// Rows zeroed at the top: round(sky_fraction * output_height).
  int skyRows() const;

  /// Empty when valid, otherwise a sentence naming the first invalid field and its allowed range.
  std::string validate() const;

  /// Corrects the combinations validate() refuses that have one obvious fix, as the preprocessor nodelet
  /// does for the panel and a parameter file: an even filter_window to the next odd one, and (patch
  /// normalization) a patch_size that does not divide the output size to the largest one below it that does
  /// (none of at least 2, as for 65x48: left for validate() to refuse). Each field within its range first.
  /// Returns one sentence per correction.
  std::vector<std::string> correctCombinations();

  /// Stable one-line "key=value;..." text, stored in map files.
  std::string serialize() const;
  /// Inverse of serialize(); false with *error set when text is malformed or invalid.
  static bool parse(const std::string& text, PreprocessingParams* params, std::string* error);

  /// A copy with the fields its normalization does not read at their defaults (patch_size and
  /// min_patch_std for eq. 3; filter_window and normalization_strength for eq. 1; those and output_gain
  /// for none): two sets with the same canonical form make the same bytes.
  PreprocessingParams canonical() const;

  /// Equal canonical forms, compared as serialized text (every field at full precision): a map's stored
  /// parameters and a live configuration are equal when they make the same bytes.
  bool operator==(const PreprocessingParams& other) const;
  bool operator!=(const PreprocessingParams& other) const { return !(*this == other); }
};

/// Converts any accepted input to 8-bit grayscale (luma weights of cv::cvtColor; mono16 scaled by
/// 1/257; float scaled by 255). Throws PreprocessingError on empty input, a type that does not match
/// the format, or NaN/inf in float input.
void toGray(const cv::Mat& input, PixelFormat format, cv::Mat& gray);

/// Float input (CV_32FC1) is read as intensity in [0, 1]; toGray clips what lies outside to black or
/// white. True when some finite value of `input` does, with *sentence naming the range found (a thermal
/// camera in kelvin, a depth image: scale it to [0, 1] first). False for any other type.
bool floatOutsideUnitRange(const cv::Mat& input, std::string* sentence);

/// Preprocessing resizes every input to output_width x output_height. True when an input of `width` x
/// `height` px is narrower or lower than that, so it is enlarged: the output holds no more detail than the
/// input (a 1 x 1 frame comes out flat, as a dark frame does, and never matches). *sentence names both
/// sizes and the fix. False for an empty size (toGray refuses it).
bool inputSmallerThanOutput(int width, int height, const PreprocessingParams& params, std::string* sentence);

/// eq. 1, SeqSLAM patch normalization, in place on an 8-bit image whose sides are multiples of
/// patch_size: every pixel of a patch becomes saturate(128 + gain * (I - mean) / std); patches with
/// std < min_std become 128. Population std (divide by patch_size^2).
void patchNormalize(cv::Mat& image, int patch_size, double min_std, double gain);

/// eq. 3, divisive contrast normalization: I' = (I - mu_g) / (1 + s * sigma_g), with mu_g and sigma_g
/// the Gaussian-weighted local mean and std (window filter_window px, sigma as cv::getGaussianKernel
/// chooses for that size, reflected borders). Output byte = saturate(128 + gain * s * I').
/// `input` 8-bit, `output` 8-bit of the same size (may not alias input).
void divisiveNormalize(const cv::Mat& input, cv::Mat& output, int filter_window, double strength,
                       double gain);

/// Whole step 1. Holds scratch buffers so that process() allocates nothing after the first frame.
class Preprocessor
{
public:
  explicit Preprocessor(const PreprocessingParams& params = PreprocessingParams());

  /// Throws PreprocessingError when params are invalid.
  void setParams(const PreprocessingParams& params);
  const PreprocessingParams& params() const { return params_; }

  /// Input frame -> preprocessed mono8 image of output_height x output_width, written into `output`.
  /// If `output` already has that size and type (e.g. it wraps an outgoing message buffer) it is
  /// written in place and not reallocated. Throws PreprocessingError for bad input.
  void process(const cv::Mat& input, PixelFormat format, cv::Mat& output);

private:
  PreprocessingParams params_;
  cv::Mat gray_, small_, scratch_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_PREPROCESSING_H
