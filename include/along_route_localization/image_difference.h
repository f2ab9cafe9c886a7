// Step 2 of the method: difference between a query and a keyframe with a horizontal shift search.
#ifndef ALONG_ROUTE_LOCALIZATION_IMAGE_DIFFERENCE_H
#define ALONG_ROUTE_LOCALIZATION_IMAGE_DIFFERENCE_H

#include <cstdint>
#include <string>
#include <vector>

namespace along_route_localization
{

enum class CostFunction
{
  kSad,    ///< sum of absolute differences of the normalized bytes
  kCensus  ///< Hamming distance of 3x3 census codes (8 bits per pixel)
};

std::string toString(CostFunction cost);
bool costFunctionFromString(const std::string& name, CostFunction* cost);

/// Best horizontal alignment of one query against one keyframe.
struct ShiftedDifference
{
  float cost = 0.0f;      ///< mean absolute difference per compared pixel (SAD) or mean differing bits (census)
  float shift_px = 0.0f;  ///< d such that query(x) ~ keyframe(x - d): scene content moved d px to the right
};

/// Compares images of one fixed size (width x height bytes, rows contiguous). Rows [first_row, height)
/// are compared (rows above are sky). The query's central strip, columns [m, width - m), is compared
/// with keyframe columns [m - d, width - m - d) for every d in [-m, m]; the smallest SAD wins.
/// With subpixel refinement the shift is the vertex of the parabola through the best cost and its two
/// neighbours (the cost stays the integer minimum).
/// With `bands` > 1 the compared rows are split into that many horizontal bands of (nearly) equal height,
/// each shifted on its own: the cost is the sum of each band's smallest SAD (a camera beside the taught
/// line sees near things, low in the image, move more than distant ones: parallax). The reported shift is
/// still that of the whole strip.
/// With `max_vertical_shift_px` V > 0 (below half the compared rows) each band (or the whole strip) is also
/// compared at every vertical offset v in [-V, V] (query row y against keyframe row y - v, over the rows
/// where both are compared rows and at least half the band's, per pixel), and each shift counts at its best
/// v: a camera that pitches and rolls (a rover on rough ground) moves the image vertically. Costs (2V + 1)
/// times the comparisons.
class ImageDifference
{
public:
  ImageDifference(int width, int height, int first_row, int max_shift_px, bool subpixel = true, int bands = 1,
                  int max_vertical_shift_px = 0);

  int width() const { return width_; }
  int height() const { return height_; }
  int maxShift() const { return max_shift_px_; }
  int bands() const { return bands_; }
  int maxVerticalShift() const { return max_vertical_shift_px_; }
  /// Pixels compared per shift: (height - first_row) * (width - 2m).
  int comparedPixels() const { return (height_ - first_row_) * (width_ - 2 * max_shift_px_); }

  /// SAD over the strip at one integer shift d, |d| <= m (unnormalized sum).
  uint32_t sadAtShift(const uint8_t* query, const uint8_t* keyframe, int shift_px) const;

  /// Best shift and its normalized cost.
  ShiftedDifference compare(const uint8_t* query, const uint8_t* keyframe) const;

  /// compare() against `count` keyframes stored contiguously (keyframe k at keyframes + k*width*height),
  /// writing costs[k] and shifts[k]. Splits the work across cores when `parallel` is set.
  void compareMany(const uint8_t* query, const uint8_t* keyframes, int count, float* costs,
                   float* shifts, bool parallel = false) const;

  int firstRow() const { return first_row_; }
  bool subpixel() const { return subpixel_; }

private:
  int width_, height_, first_row_, max_shift_px_;
  bool subpixel_;
  int bands_;
  int max_vertical_shift_px_;
};

/// 2x2 box average, rounded to nearest: half has (width / 2) x (height / 2) pixels, an odd last column or
/// row is dropped. The coarse global search (Localizer, coarse_search_keyframes) compares these images.
void halveImage(const uint8_t* image, int width, int height, uint8_t* half);
/// halveImage of `count` images stored contiguously, into `halves` (contiguous too). Same bytes; one
/// vectorized, parallel cv::resize (INTER_AREA) over the whole stack when width and height are even.
void halveImages(const uint8_t* images, size_t count, int width, int height, uint8_t* halves);

/// 3x3 census transform: bit b of the output is set when neighbour b is darker than the centre
/// (neighbours in row-major order, centre skipped). Border pixels compare against replicated edges.
void censusTransform(const uint8_t* image, int width, int height, uint8_t* codes);

/// Census cost: for every shift like ImageDifference, but the per-pixel cost is popcount(q ^ k).
class CensusDifference
{
public:
  CensusDifference(int width, int height, int first_row, int max_shift_px, bool subpixel = true);
  /// query and keyframe are census codes (see censusTransform).
  ShiftedDifference compare(const uint8_t* query_codes, const uint8_t* keyframe_codes) const;

private:
  ImageDifference geometry_;
};

/// Mean |byte - 128| over rows [first_row, height): how much normalized texture an image carries.
/// Near-black or blank frames normalize to (almost) flat 128 and score near 0.
float textureEnergy(const uint8_t* image, int width, int height, int first_row);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_IMAGE_DIFFERENCE_H
