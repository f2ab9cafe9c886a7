// Step 3b of the method: the K x N ring buffer of enhanced difference vectors.
#ifndef ALONG_ROUTE_LOCALIZATION_COST_RING_BUFFER_H
#define ALONG_ROUTE_LOCALIZATION_COST_RING_BUFFER_H

#include <cstddef>
#include <cstdint>
#include <vector>

namespace along_route_localization
{

/// The last K enhanced difference vectors, newest first. A row covers a band of consecutive keyframes
/// [first, first + width) -- the whole map while searching globally, the search band while tracking --
/// so memory is K x N floats at most, fixed at construction and independent of how many frames were
/// processed. Lookups outside a row's band return a caller-chosen "missing" cost.
class CostRingBuffer
{
public:
  /// rows = K >= 1, max_width = N >= 1 (the map size).
  CostRingBuffer(int rows = 1, int max_width = 1);

  /// Appends a row covering [first_keyframe, first_keyframe + width) and returns its storage
  /// (width floats) to fill; the oldest row is dropped when K rows are held. 0 < width <= max_width.
  /// repeated_query: the row's query showed the same view as the previous row's (the camera stood still).
  float* appendRow(int first_keyframe, int width, bool repeated_query = false);

  /// Changes K and/or N keeping the newest min(size(), rows) rows (bands clipped to the new width).
  void resize(int rows, int max_width);
  void clear();

  int capacity() const { return capacity_; }
  int maxWidth() const { return max_width_; }
  int size() const { return size_; }

  /// age 0 is the newest row, age size()-1 the oldest.
  int rowFirst(int age) const;
  int rowWidth(int age) const;
  const float* row(int age) const;
  /// The repeated_query flag given to appendRow for the row of that age.
  bool repeatedQuery(int age) const { return bands_[slot(age)].repeated_query; }
  /// Whether the row of that age brings a new view into the window of the newest `rows` rows: it is not a
  /// repeated query, or it is the window's oldest row (the view it repeats has left the window).
  bool newView(int age, int rows) const { return !repeatedQuery(age) || age == rows - 1; }
  /// The rows among the newest `rows` (at most size()) that bring a new view: the distinct views held.
  int distinctViews(int rows) const;

  /// Cost of `keyframe` in the row of that age, or `missing` outside the row's band.
  float at(int age, int keyframe, float missing) const
  {
    const Band& band = bands_[slot(age)];
    const int offset = keyframe - band.first;
    return (offset >= 0 && offset < band.width) ? data_[static_cast<size_t>(slot(age)) * max_width_ + offset] :
                                                  missing;
  }

  /// Bytes held by the cost storage (K x N floats).
  size_t memoryBytes() const { return data_.size() * sizeof(float); }

private:
  struct Band
  {
    int first = 0;
    int width = 0;
    bool repeated_query = false;
  };
  int slot(int age) const { return (newest_ - age + capacity_) % capacity_; }

  int capacity_, max_width_;
  int newest_ = -1;
  int size_ = 0;
  std::vector<Band> bands_;
  std::vector<float> data_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_COST_RING_BUFFER_H
