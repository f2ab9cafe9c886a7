// The debug image (debug_image.h): layout numbers worked out by hand from the margins (56 px left, 16 px
// right, 76 px above the matrix, 92 px below, at least 640 px wide), and pixels of hand-placed costs,
// path and match.
#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "along_route_localization/debug_image.h"

namespace arl = along_route_localization;

namespace
{

// Rows (newest last) over keyframes [0, 10): row r has cost `costs[r][k]` in its band [first, first + width).
arl::CostRingBuffer ringOf(int capacity, const std::vector<std::vector<float>>& rows, int first, int width)
{
  arl::CostRingBuffer ring(capacity, 10);
  for (const auto& costs : rows)
  {
    float* out = ring.appendRow(first, width);
    for (int x = 0; x < width; ++x)
      out[x] = costs[static_cast<size_t>(first + x)];
  }
  return ring;
}

cv::Vec3b at(const cv::Mat& image, cv::Point p) { return image.at<cv::Vec3b>(p); }

// A pixel inside cell (row, keyframe) away from its centre (where the path is drawn): 1 px from the corner.
cv::Point cellCorner(const arl::DebugImageLayout& layout, int row, int keyframe)
{
  const cv::Point centre = layout.cellCentre(row, keyframe);
  return cv::Point(centre.x - layout.cell_px / 2 + 1, centre.y - layout.cell_px / 2 + 1);
}

int countNot(const cv::Mat& image, const cv::Rect& area, const cv::Vec3b& colour)
{
  int count = 0;
  for (int y = area.y; y < area.y + area.height; ++y)
    for (int x = area.x; x < area.x + area.width; ++x)
      count += image.at<cv::Vec3b>(y, x) != colour;
  return count;
}

int count(const cv::Mat& image, const cv::Rect& area, const cv::Vec3b& colour)
{
  return area.area() - countNot(image, area, colour);
}

}  // namespace

TEST(DebugImage, LayoutIsLargeEnoughForAViewer)
{
  // The nodelet's default window: 2 * search_radius 40 + 1 = 81 keyframes, K = 30, 8 px per cell.
  arl::DebugImageContent content;
  content.keyframes = 81;
  content.cell_px = 8;
  const arl::DebugImageLayout layout = arl::debugImageLayout(content, 30);
  EXPECT_EQ(cv::Rect(56, 76, 648, 240), layout.matrix);
  EXPECT_EQ(cv::Size(56 + 648 + 16, 76 + 240 + 92), layout.size);  // 720 x 408
  // A narrow window is still 640 px wide: the header's text fits.
  content.keyframes = 11;
  content.cell_px = 4;
  const arl::DebugImageLayout narrow = arl::debugImageLayout(content, 5);
  EXPECT_EQ(cv::Size(640, 76 + 20 + 92), narrow.size);
  EXPECT_EQ(cv::Point(56 + 3 * 4 + 2, 76 + 4 * 4 + 2), narrow.cellCentre(4, 3));
}

TEST(DebugImage, RendersCostsPathAndMatchWhereTheyBelong)
{
  // Three frames over keyframes 0-9, each row's band [2, 8); K = 5 rows drawn, so the top two are empty.
  std::vector<std::vector<float>> rows(3, std::vector<float>(10, 0.0f));
  rows[2][2] = -2.0f;  // newest frame, keyframe 2: a perfect match (black)
  rows[1][5] = 2.0f;   // middle frame, keyframe 5: as different as it gets (white)
  rows[0][6] = 1.0f;   // oldest frame, keyframe 6: 127.5 + 127.5 / 2 = 191.25 -> 191
  const arl::CostRingBuffer ring = ringOf(5, rows, 2, 6);
  arl::DebugImageContent content;
  content.first_keyframe = 0;
  content.keyframes = 10;
  content.cell_px = 8;
  content.cost_clamp = 2.0f;
  content.path = { 3, 4, 4 };  // oldest first: rows 2, 3, 4 of the 5 drawn
  content.match_keyframe = 4;
  content.status = "tracking";
  content.confidence = 0.75;
  cv::Mat image;
  arl::renderDebugImage(ring, content, image);
  const arl::DebugImageLayout layout = arl::debugImageLayout(content, 5);
  ASSERT_EQ(CV_8UC3, image.type());
  ASSERT_EQ(layout.size, image.size());

  // Costs: rows are frames, newest at the bottom (row 4 = age 0).
  EXPECT_EQ(cv::Vec3b(0, 0, 0), at(image, cellCorner(layout, 4, 2)));
  EXPECT_EQ(cv::Vec3b(255, 255, 255), at(image, cellCorner(layout, 3, 5)));
  EXPECT_EQ(cv::Vec3b(191, 191, 191), at(image, cellCorner(layout, 2, 6)));
  EXPECT_EQ(cv::Vec3b(128, 128, 128), at(image, cellCorner(layout, 2, 7)));  // cost 0: 127.5 rounds to 128
  // Outside the rows' band, and rows older than the ring buffer holds: not computed.
  EXPECT_EQ(arl::kDebugNotComputed, at(image, cellCorner(layout, 4, 9)));
  EXPECT_EQ(arl::kDebugNotComputed, at(image, cellCorner(layout, 0, 5)));

  // The path at its cells' centres, not elsewhere.
  EXPECT_EQ(arl::kDebugPath, at(image, layout.cellCentre(2, 3)));
  EXPECT_EQ(arl::kDebugPath, at(image, layout.cellCentre(3, 4)));
  EXPECT_EQ(arl::kDebugPath, at(image, layout.cellCentre(4, 4)));
  EXPECT_NE(arl::kDebugPath, at(image, layout.cellCentre(4, 2)));
  EXPECT_NE(arl::kDebugPath, at(image, layout.cellCentre(1, 3)));

  // The match: its newest-row cell outlined (2 px beyond the cell) in green.
  const cv::Point match = layout.cellCentre(4, 4);
  EXPECT_EQ(arl::kDebugMatch, at(image, cv::Point(match.x - 8 / 2 - 2, match.y)));
  EXPECT_EQ(arl::kDebugMatch, at(image, cv::Point(match.x, match.y + 8 / 2 + 2)));

  // Status, match and confidence are written in the header; the status box is green for tracking.
  EXPECT_GT(countNot(image, layout.header, arl::kDebugBackground), 500);
  EXPECT_EQ(cv::Vec3b(0, 140, 0), at(image, cv::Point(10, 8)));
  content.status = "lost";
  cv::Mat lost;
  arl::renderDebugImage(ring, content, lost);
  EXPECT_EQ(cv::Vec3b(0, 0, 200), at(lost, cv::Point(10, 8)));

  // Row labels left of the matrix and keyframe numbers under it.
  EXPECT_GT(countNot(image, cv::Rect(0, layout.matrix.y, layout.matrix.x - 4, layout.matrix.height), arl::kDebugBackground), 20);
  EXPECT_GT(countNot(image, cv::Rect(layout.matrix.x, layout.matrix.br().y + 6, layout.matrix.width, 14),
                     arl::kDebugBackground), 20);
  // The colour scale: similar (black) on the left, different (white) on the right.
  const cv::Rect& scale = layout.colour_scale;
  EXPECT_LT(at(image, cv::Point(scale.x + 1, scale.y + scale.height / 2))[0], 10);
  EXPECT_GT(at(image, cv::Point(scale.x + scale.width - 2, scale.y + scale.height / 2))[0], 245);
}

TEST(DebugImage, PathOutsideTheWindowStaysInsideTheMatrix)
{
  std::vector<std::vector<float>> rows(4, std::vector<float>(10, 0.0f));
  const arl::CostRingBuffer ring = ringOf(4, rows, 0, 10);
  arl::DebugImageContent content;
  content.first_keyframe = 3;
  content.keyframes = 4;  // keyframes 3-6
  content.cell_px = 8;
  content.path = { 0, 1, 5, 9 };  // leaves the window on both sides
  content.match_keyframe = 9;     // outside: no outline, the header says so
  content.status = "tracking";
  cv::Mat image;
  arl::renderDebugImage(ring, content, image);
  const arl::DebugImageLayout layout = arl::debugImageLayout(content, 4);
  EXPECT_EQ(arl::kDebugPath, at(image, layout.cellCentre(2, 5)));
  // No path colour left of the matrix or between its bottom and the legend line.
  EXPECT_EQ(0, count(image, cv::Rect(0, layout.matrix.y, layout.matrix.x, layout.matrix.height), arl::kDebugPath));
  EXPECT_EQ(0, count(image, cv::Rect(0, layout.matrix.br().y, image.cols, 30), arl::kDebugPath));
  EXPECT_EQ(0, count(image, cv::Rect(0, layout.matrix.br().y, image.cols, 30), arl::kDebugMatch));
}

TEST(DebugImage, RowsDefaultToTheRingBufferCapacityAndBadSizesAreRefused)
{
  const arl::CostRingBuffer ring(7, 10);
  arl::DebugImageContent content;
  content.keyframes = 10;
  content.cell_px = 4;
  cv::Mat image;
  arl::renderDebugImage(ring, content, image);
  EXPECT_EQ(76 + 7 * 4 + 92, image.rows);  // a constant size while the ring buffer fills
  content.keyframes = 0;
  EXPECT_THROW(arl::renderDebugImage(ring, content, image), std::invalid_argument);
  content.keyframes = 10;
  content.cell_px = 0;
  EXPECT_THROW(arl::renderDebugImage(ring, content, image), std::invalid_argument);
}

TEST(DebugImage, RendersIntoTheCallersBuffer)
{
  // The nodelet wraps the message's data: an image of the right size and type is drawn in place.
  const arl::CostRingBuffer ring(3, 10);
  arl::DebugImageContent content;
  content.keyframes = 10;
  content.cell_px = 8;
  const arl::DebugImageLayout layout = arl::debugImageLayout(content, 3);
  std::vector<uint8_t> buffer(static_cast<size_t>(layout.size.area()) * 3, 7);
  cv::Mat wrapped(layout.size, CV_8UC3, buffer.data());
  arl::renderDebugImage(ring, content, wrapped);
  EXPECT_EQ(buffer.data(), wrapped.data);
  EXPECT_EQ(255, buffer[0]);  // the background, drawn into the buffer
}
