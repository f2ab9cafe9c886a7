// The localizer's debug image, read as the paper's figure 4: the window of the K x N cost matrix (eq. 2,
// rows = frames, newest at the bottom; columns = keyframes) with the DTW path, the current match, the
// status and confidence, axes with frame ages and keyframe numbers, a colour scale and a legend.
#ifndef ALONG_ROUTE_LOCALIZATION_DEBUG_IMAGE_H
#define ALONG_ROUTE_LOCALIZATION_DEBUG_IMAGE_H

#include <opencv2/core.hpp>

#include <string>
#include <vector>

#include "along_route_localization/cost_ring_buffer.h"

namespace along_route_localization
{

/// What the debug image shows besides the ring buffer's costs.
struct DebugImageContent
{
  int first_keyframe = 0;     ///< first keyframe column
  int keyframes = 1;          ///< columns: keyframes [first_keyframe, first_keyframe + keyframes), >= 1
  int rows = 0;               ///< frame rows drawn (the window K); 0: the ring buffer's capacity
  std::vector<int> path;      ///< DTW path, one keyframe per frame, oldest first, ending at the newest row
  int match_keyframe = -1;    ///< the keyframe reported for the newest frame; -1: no answer
  std::string status;         ///< "tracking", "initializing", "lost", "end_of_route" (coloured), or any text
  double confidence = -1.0;   ///< in [0, 1]; < 0: not shown
  float cost_clamp = 2.0f;    ///< the colour scale runs over [-cost_clamp, +cost_clamp] (contrast_clamp, eq. 2)
  int cell_px = 8;            ///< pixels per cost-matrix cell, >= 1
};

/// Where the parts of the debug image lie, in pixels (a function of the content's numbers only).
struct DebugImageLayout
{
  cv::Size size;              ///< the whole image
  cv::Rect header;            ///< status, match and confidence text
  cv::Rect matrix;            ///< the cost matrix: rows x keyframes cells of cell_px
  cv::Rect colour_scale;      ///< the vertical colour bar, high cost at the top
  int rows = 0, cell_px = 1, first_keyframe = 0, keyframes = 1;

  /// Centre of the cell of frame row `row` (0 = the oldest drawn, rows - 1 = the newest) and `keyframe`.
  cv::Point cellCentre(int row, int keyframe) const;
};

/// Layout for `rows` frame rows (content.rows, or the ring buffer's capacity when that is 0). The image is
/// at least kDebugImageMinWidth px wide, so the header's text fits and a viewer shows it at a readable size.
constexpr int kDebugImageMinWidth = 640;
DebugImageLayout debugImageLayout(const DebugImageContent& content, int rows);

/// Colours (BGR), for users reading the legend and for tests.
const cv::Vec3b kDebugBackground(255, 255, 255);
const cv::Vec3b kDebugNotComputed(140, 80, 40);  ///< outside the row's band, or no frame yet: dark blue
const cv::Vec3b kDebugPath(0, 0, 230);           ///< the DTW path: red
const cv::Vec3b kDebugMatch(0, 200, 0);          ///< the current match's cell outline and axis marker: green

/// Gray level of an eq. 2 cost: -clamp (a match) black, +clamp white, linear between.
uint8_t debugImageGray(float cost, float clamp);

/// Renders the debug image into `image` (BGR8 of debugImageLayout(...).size; reallocated unless it already
/// is that, so a caller may wrap a message's buffer). Cell (row, keyframe) shows costs.at(age, keyframe) with
/// age = rows - 1 - row; rows older than the ring buffer holds, and keyframes outside a row's band, are
/// drawn as not computed. Throws std::invalid_argument for keyframes < 1 or cell_px < 1.
void renderDebugImage(const CostRingBuffer& costs, const DebugImageContent& content, cv::Mat& image);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_DEBUG_IMAGE_H
