#include "along_route_localization/cost_ring_buffer.h"

#include <algorithm>
#include <stdexcept>

namespace along_route_localization
{

CostRingBuffer::CostRingBuffer(int rows, int max_width) : capacity_(0), max_width_(0)
{
  resize(rows, max_width);
}

float* CostRingBuffer::appendRow(int first_keyframe, int width, bool repeated_query)
{
  if (width <= 0 || width > max_width_)
    throw std::invalid_argument("CostRingBuffer::appendRow: width must be in [1, max_width]");
  newest_ = (newest_ + 1) % capacity_;
  size_ = std::min(size_ + 1, capacity_);
  bands_[newest_] = Band{ first_keyframe, width, repeated_query };
  return data_.data() + static_cast<size_t>(newest_) * max_width_;
}

void CostRingBuffer::resize(int rows, int max_width)
{
  if (rows < 1 || max_width < 1)
    throw std::invalid_argument("CostRingBuffer: rows and max_width must be >= 1");
  if (rows == capacity_ && max_width == max_width_)
    return;
  // Re-pack the newest rows oldest-first into the new storage, so ages are kept.
  const int keep = std::min(size_, rows);
  std::vector<Band> bands(rows);
  std::vector<float> data(static_cast<size_t>(rows) * max_width);
  for (int age = keep - 1, slot_new = 0; age >= 0; --age, ++slot_new)
  {
    const Band& old = bands_[slot(age)];
    const int width = std::min(old.width, max_width);
    bands[slot_new] = Band{ old.first, width, old.repeated_query };
    std::copy_n(data_.data() + static_cast<size_t>(slot(age)) * max_width_, width,
                data.data() + static_cast<size_t>(slot_new) * max_width);
  }
  capacity_ = rows;
  max_width_ = max_width;
  bands_.swap(bands);
  data_.swap(data);
  size_ = keep;
  newest_ = keep - 1;
  if (newest_ < 0)
    newest_ = capacity_ - 1;  // next append lands in slot 0
}

int CostRingBuffer::distinctViews(int rows) const
{
  int distinct = 0;
  for (int age = 0; age < rows; ++age)
    distinct += newView(age, rows) ? 1 : 0;
  return distinct;
}

void CostRingBuffer::clear()
{
  size_ = 0;
  newest_ = capacity_ - 1;
}

int CostRingBuffer::rowFirst(int age) const
{
  return bands_[slot(age)].first;
}

int CostRingBuffer::rowWidth(int age) const
{
  return bands_[slot(age)].width;
}

const float* CostRingBuffer::row(int age) const
{
  return data_.data() + static_cast<size_t>(slot(age)) * max_width_;
}

}  // namespace along_route_localization
