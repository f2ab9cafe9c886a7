#include "along_route_localization/debug_image.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace along_route_localization
{

namespace
{

constexpr int kLeftMargin = 56;     // row labels
constexpr int kRightMargin = 16;
constexpr int kHeaderHeight = 56;   // two lines of text
constexpr int kMatrixTop = 76;      // header, then the rows' axis title
constexpr int kBelowMatrix = 92;    // ticks, keyframe numbers, axis title, legend, colour scale
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kText(30, 30, 30);
const cv::Scalar kMutedText(90, 90, 90);

cv::Scalar scalar(const cv::Vec3b& colour) { return cv::Scalar(colour[0], colour[1], colour[2]); }

int textWidth(const std::string& text, double scale, int thickness)
{
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline).width;
}

void text(cv::Mat& image, const std::string& line, cv::Point origin, double scale, const cv::Scalar& colour,
          int thickness = 1)
{
  cv::putText(image, line, origin, kFont, scale, colour, thickness, cv::LINE_AA);
}

cv::Scalar statusColour(const std::string& status)
{
  if (status == "tracking")
    return cv::Scalar(0, 140, 0);
  if (status == "end_of_route")
    return cv::Scalar(140, 110, 0);
  if (status == "initializing")
    return cv::Scalar(0, 120, 230);
  if (status == "lost")
    return cv::Scalar(0, 0, 200);
  return cv::Scalar(110, 110, 110);
}

std::string upper(std::string s)
{
  for (char& c : s)
    c = c == '_' ? ' ' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// Keyframe numbers every `step` keyframes, step from 1, 2, 5, 10, 20, 50, ... so that labels of the
// largest keyframe number do not overlap.
int tickStep(int cell_px, int last_keyframe)
{
  const int label_px = textWidth(std::to_string(std::max(0, last_keyframe)), 0.4, 1) + 12;
  for (int step = 1;; step *= 10)
    for (int factor : { 1, 2, 5 })
      if (static_cast<long long>(step) * factor * cell_px >= label_px || step > 100000000)
        return step * factor;
}

}  // namespace

cv::Point DebugImageLayout::cellCentre(int row, int keyframe) const
{
  return cv::Point(matrix.x + (keyframe - first_keyframe) * cell_px + cell_px / 2, matrix.y + row * cell_px + cell_px / 2);
}

DebugImageLayout debugImageLayout(const DebugImageContent& content, int rows)
{
  if (content.keyframes < 1 || content.cell_px < 1)
    throw std::invalid_argument("renderDebugImage: keyframes and cell_px must be >= 1");
  DebugImageLayout layout;
  layout.rows = std::max(1, rows);
  layout.cell_px = content.cell_px;
  layout.first_keyframe = content.first_keyframe;
  layout.keyframes = content.keyframes;
  layout.matrix = cv::Rect(kLeftMargin, kMatrixTop, content.keyframes * content.cell_px, layout.rows * content.cell_px);
  const int width = std::max(kDebugImageMinWidth, layout.matrix.x + layout.matrix.width + kRightMargin);
  layout.size = cv::Size(width, layout.matrix.y + layout.matrix.height + kBelowMatrix);
  layout.header = cv::Rect(0, 0, width, kHeaderHeight);
  // On the bottom line, after its label: a horizontal colour bar, low cost (similar) on the left.
  layout.colour_scale = cv::Rect(236, layout.size.height - 21, 160, 12);
  return layout;
}

uint8_t debugImageGray(float cost, float clamp)
{
  if (!(clamp > 0.0f))
    clamp = 1.0f;
  return cv::saturate_cast<uint8_t>(127.5f + 127.5f * cost / clamp);
}

void renderDebugImage(const CostRingBuffer& costs, const DebugImageContent& content, cv::Mat& image)
{
  const int rows = content.rows > 0 ? content.rows : costs.capacity();
  const DebugImageLayout layout = debugImageLayout(content, rows);
  image.create(layout.size, CV_8UC3);
  image.setTo(scalar(kDebugBackground));

  // The cost matrix, one pixel per cell, then scaled up.
  cv::Mat cells(layout.rows, layout.keyframes, CV_8UC3, scalar(kDebugNotComputed));
  const int held = std::min(costs.size(), layout.rows);
  for (int age = 0; age < held; ++age)
  {
    cv::Vec3b* out = cells.ptr<cv::Vec3b>(layout.rows - 1 - age);
    for (int x = 0; x < layout.keyframes; ++x)
    {
      const float c = costs.at(age, content.first_keyframe + x, std::nanf(""));
      if (std::isnan(c))
        continue;
      const uint8_t gray = debugImageGray(c, content.cost_clamp);
      out[x] = cv::Vec3b(gray, gray, gray);
    }
  }
  cv::Mat matrix = image(layout.matrix);
  cv::resize(cells, matrix, matrix.size(), 0.0, 0.0, cv::INTER_NEAREST);

  // The DTW path through the cell centres (drawn inside the matrix only), its last row the newest frame.
  const int path_rows = std::min(static_cast<int>(content.path.size()), layout.rows);
  const int path_offset = static_cast<int>(content.path.size()) - path_rows;
  const int thickness = std::max(1, layout.cell_px / 4);
  cv::Point previous;
  for (int i = 0; i < path_rows; ++i)
  {
    const int row = layout.rows - path_rows + i;
    const cv::Point centre = layout.cellCentre(row, content.path[static_cast<size_t>(path_offset + i)]) -
                             layout.matrix.tl();
    if (i == 0)
      cv::line(matrix, centre, centre, scalar(kDebugPath), thickness);
    else
      cv::line(matrix, previous, centre, scalar(kDebugPath), thickness);
    previous = centre;
  }

  // Frame axis: ages of the rows, newest ("t") at the bottom.
  text(image, "frame", cv::Point(6, kMatrixTop - 8), 0.4, kMutedText);
  const int row_label_every = layout.cell_px >= 12 ? 1 : (layout.cell_px >= 6 ? 5 : 10);
  for (int age = 0; age < layout.rows; age += row_label_every)
  {
    const std::string label = age == 0 ? "t" : "t-" + std::to_string(age);
    const int row = layout.rows - 1 - age;
    const int y = layout.matrix.y + row * layout.cell_px + layout.cell_px / 2;
    cv::line(image, cv::Point(layout.matrix.x - 4, y), cv::Point(layout.matrix.x - 1, y), kText);
    text(image, label, cv::Point(layout.matrix.x - 7 - textWidth(label, 0.4, 1), y + 5), 0.4, kText);
  }

  // Keyframe axis: numbers under the columns.
  const int bottom = layout.matrix.y + layout.matrix.height;
  const int last = content.first_keyframe + layout.keyframes - 1;
  const int step = tickStep(layout.cell_px, last);
  for (int k = ((std::max(0, content.first_keyframe) + step - 1) / step) * step; k <= last; k += step)
  {
    const int x = layout.matrix.x + (k - content.first_keyframe) * layout.cell_px + layout.cell_px / 2;
    cv::line(image, cv::Point(x, bottom), cv::Point(x, bottom + 4), kText);
    const std::string label = std::to_string(k);
    text(image, label, cv::Point(x - textWidth(label, 0.4, 1) / 2, bottom + 18), 0.4, kText);
  }
  text(image, "keyframe (map)", cv::Point(layout.matrix.x + layout.matrix.width / 2 - 50, bottom + 36), 0.45, kMutedText);

  // The current match: its cell on the newest row outlined, a marker under the axis.
  const bool match_shown =
      content.match_keyframe >= content.first_keyframe && content.match_keyframe <= last;
  if (match_shown)
  {
    const cv::Point centre = layout.cellCentre(layout.rows - 1, content.match_keyframe);
    const int half = layout.cell_px / 2 + 2;
    cv::rectangle(image, cv::Rect(centre.x - half, centre.y - half, 2 * half + 1, 2 * half + 1),
                  scalar(kDebugMatch), 2);
    const std::vector<cv::Point> marker = { cv::Point(centre.x, bottom + 1), cv::Point(centre.x - 4, bottom + 7),
                                            cv::Point(centre.x + 4, bottom + 7) };
    cv::fillConvexPoly(image, marker, scalar(kDebugMatch), cv::LINE_AA);
  }

  // Header: status, match, confidence; then what the picture is.
  const std::string status = content.status.empty() ? "NO STATUS" : upper(content.status);
  const int status_width = textWidth(status, 0.6, 2) + 16;
  cv::rectangle(image, cv::Rect(8, 6, status_width, 26), statusColour(content.status), cv::FILLED);
  text(image, status, cv::Point(16, 26), 0.6, cv::Scalar(255, 255, 255), 2);
  int x = 8 + status_width + 16;
  const std::string match = content.match_keyframe >= 0 ? "keyframe " + std::to_string(content.match_keyframe) +
                                                              (match_shown ? "" : " (outside the window)") :
                                                          "no keyframe";
  text(image, match, cv::Point(x, 26), 0.6, kText, 1);
  x += textWidth(match, 0.6, 1) + 24;
  if (content.confidence >= 0.0)
  {
    char confidence[32];
    std::snprintf(confidence, sizeof(confidence), "confidence %.2f", std::min(1.0, content.confidence));
    text(image, confidence, cv::Point(x, 26), 0.6, kText, 1);
    x += textWidth(confidence, 0.6, 1) + 10;
    const int bar_width = std::max(20, std::min(100, layout.size.width - x - 10));
    cv::rectangle(image, cv::Rect(x, 13, bar_width, 12), cv::Scalar(200, 200, 200), cv::FILLED);
    cv::rectangle(image, cv::Rect(x, 13, static_cast<int>(std::lround(bar_width * std::min(1.0, content.confidence))), 12),
                  statusColour(content.status), cv::FILLED);
    cv::rectangle(image, cv::Rect(x, 13, bar_width, 12), kMutedText, 1);
  }
  const std::string caption = "cost matrix: last " + std::to_string(layout.rows) +
                              " frames (rows, newest at the bottom) x keyframes " +
                              std::to_string(std::max(0, content.first_keyframe)) + "-" + std::to_string(last);
  text(image, caption, cv::Point(8, 48), 0.42, kMutedText);

  // Legend: path, match, not computed; below it the colour scale.
  int y = layout.size.height - 32;
  x = 8;
  cv::line(image, cv::Point(x, y - 4), cv::Point(x + 22, y - 4), scalar(kDebugPath), 3);
  const std::string path_entry = content.path.empty() ? "DTW path (none: the whole map searched)" : "DTW path";
  text(image, path_entry, cv::Point(x + 28, y), 0.42, kText);
  x += 28 + textWidth(path_entry, 0.42, 1) + 18;
  cv::rectangle(image, cv::Rect(x, y - 11, 12, 12), scalar(kDebugMatch), 2);
  text(image, "current match", cv::Point(x + 18, y), 0.42, kText);
  x += 18 + textWidth("current match", 0.42, 1) + 18;
  cv::rectangle(image, cv::Rect(x, y - 11, 12, 12), scalar(kDebugNotComputed), cv::FILLED);
  text(image, "not computed", cv::Point(x + 18, y), 0.42, kText);

  const cv::Rect& scale = layout.colour_scale;
  y = scale.y + scale.height - 1;
  for (int i = 0; i < scale.width; ++i)
  {
    const float cost = content.cost_clamp * (2.0f * (static_cast<float>(i) + 0.5f) / static_cast<float>(scale.width) - 1.0f);
    const uint8_t gray = debugImageGray(cost, content.cost_clamp);
    cv::line(image, cv::Point(scale.x + i, scale.y), cv::Point(scale.x + i, scale.y + scale.height - 1),
             cv::Scalar(gray, gray, gray));
  }
  cv::rectangle(image, scale, kMutedText, 1);
  char label[64];
  std::snprintf(label, sizeof(label), "cost (eq. 2): similar %.1f", static_cast<double>(-content.cost_clamp));
  text(image, label, cv::Point(scale.x - 6 - textWidth(label, 0.42, 1), y), 0.42, kText);
  std::snprintf(label, sizeof(label), "+%.1f different", static_cast<double>(content.cost_clamp));
  text(image, label, cv::Point(scale.x + scale.width + 6, y), 0.42, kText);
}

}  // namespace along_route_localization
