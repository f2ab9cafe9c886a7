// Step 3b (cost_ring_buffer.h): K x N ring buffer of cost rows with bands.
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/cost_ring_buffer.h"

namespace arl = along_route_localization;

namespace
{

// Appends row number r covering [first, first + width) filled with 100 * r + offset.
void appendNumbered(arl::CostRingBuffer& buffer, int r, int first, int width)
{
  float* row = buffer.appendRow(first, width);
  ASSERT_NE(nullptr, row);
  for (int j = 0; j < width; ++j)
    row[j] = 100.0f * r + j;
}

}  // namespace

TEST(CostRingBuffer, AppendBeyondCapacityDropsTheOldest)
{
  // K = 3, N = 6. Rows r = 0..4 cover [r, r + 2) ... so after 5 appends rows 2, 3, 4 remain:
  // age 0 = row 4, age 1 = row 3, age 2 = row 2.
  arl::CostRingBuffer buffer(3, 6);
  EXPECT_EQ(3, buffer.capacity());
  EXPECT_EQ(6, buffer.maxWidth());
  EXPECT_EQ(0, buffer.size());
  for (int r = 0; r < 5; ++r)
  {
    appendNumbered(buffer, r, r, 2);
    EXPECT_EQ(std::min(r + 1, 3), buffer.size()) << "after row " << r;
    EXPECT_EQ(r, buffer.rowFirst(0));
    EXPECT_FLOAT_EQ(100.0f * r, buffer.row(0)[0]);
  }
  for (int age = 0; age < 3; ++age)
  {
    const int r = 4 - age;
    EXPECT_EQ(r, buffer.rowFirst(age)) << "age " << age;
    EXPECT_EQ(2, buffer.rowWidth(age)) << "age " << age;
    EXPECT_FLOAT_EQ(100.0f * r, buffer.row(age)[0]) << "age " << age;
    EXPECT_FLOAT_EQ(100.0f * r + 1, buffer.row(age)[1]) << "age " << age;
    EXPECT_FLOAT_EQ(100.0f * r + 1, buffer.at(age, r + 1, -1.0f)) << "age " << age;
  }
  // Many more appends: still K rows, newest first.
  for (int r = 5; r < 1000; ++r)
    appendNumbered(buffer, r, r % 4, 3);
  EXPECT_EQ(3, buffer.size());
  EXPECT_FLOAT_EQ(99900.0f, buffer.at(0, 999 % 4, -1.0f));
  EXPECT_FLOAT_EQ(99800.0f + 2, buffer.at(1, 998 % 4 + 2, -1.0f));
  EXPECT_FLOAT_EQ(99700.0f, buffer.at(2, 997 % 4, -1.0f));
}

TEST(CostRingBuffer, LookupsOutsideABandReturnMissing)
{
  // A row covering keyframes [5, 8) with costs 1 2 3.
  arl::CostRingBuffer buffer(2, 10);
  float* row = buffer.appendRow(5, 3);
  row[0] = 1.0f;
  row[1] = 2.0f;
  row[2] = 3.0f;
  EXPECT_EQ(5, buffer.rowFirst(0));
  EXPECT_EQ(3, buffer.rowWidth(0));
  EXPECT_FLOAT_EQ(-7.0f, buffer.at(0, 4, -7.0f));
  EXPECT_FLOAT_EQ(1.0f, buffer.at(0, 5, -7.0f));
  EXPECT_FLOAT_EQ(2.0f, buffer.at(0, 6, -7.0f));
  EXPECT_FLOAT_EQ(3.0f, buffer.at(0, 7, -7.0f));
  EXPECT_FLOAT_EQ(-7.0f, buffer.at(0, 8, -7.0f));
  EXPECT_FLOAT_EQ(0.5f, buffer.at(0, 0, 0.5f));
  // A full-width row next: the older band is unchanged.
  float* full = buffer.appendRow(0, 10);
  for (int j = 0; j < 10; ++j)
    full[j] = 10.0f + j;
  EXPECT_FLOAT_EQ(19.0f, buffer.at(0, 9, -7.0f));
  EXPECT_FLOAT_EQ(-7.0f, buffer.at(1, 9, -7.0f));
  EXPECT_FLOAT_EQ(2.0f, buffer.at(1, 6, -7.0f));
}

TEST(CostRingBuffer, ResizeKeepsTheNewestRows)
{
  arl::CostRingBuffer buffer(4, 5);
  for (int r = 0; r < 6; ++r)  // rows 2..5 held after wrapping
    appendNumbered(buffer, r, 0, 5);
  buffer.resize(2, 5);  // keeps rows 5 (age 0) and 4 (age 1)
  EXPECT_EQ(2, buffer.capacity());
  ASSERT_EQ(2, buffer.size());
  EXPECT_FLOAT_EQ(500.0f, buffer.row(0)[0]);
  EXPECT_FLOAT_EQ(404.0f, buffer.row(1)[4]);

  buffer.resize(6, 5);  // growing keeps both
  EXPECT_EQ(6, buffer.capacity());
  ASSERT_EQ(2, buffer.size());
  EXPECT_FLOAT_EQ(500.0f, buffer.row(0)[0]);
  EXPECT_FLOAT_EQ(400.0f, buffer.row(1)[0]);
  appendNumbered(buffer, 6, 0, 5);
  ASSERT_EQ(3, buffer.size());
  EXPECT_FLOAT_EQ(600.0f, buffer.row(0)[0]);
  EXPECT_FLOAT_EQ(500.0f, buffer.row(1)[0]);
  EXPECT_FLOAT_EQ(403.0f, buffer.row(2)[3]);

  buffer.resize(6, 3);  // narrower: bands clipped to 3, first values kept
  EXPECT_EQ(3, buffer.maxWidth());
  ASSERT_EQ(3, buffer.size());
  for (int age = 0; age < 3; ++age)
  {
    EXPECT_EQ(3, buffer.rowWidth(age)) << "age " << age;
    EXPECT_FLOAT_EQ(100.0f * (6 - age) + 2, buffer.at(age, 2, -1.0f)) << "age " << age;
    EXPECT_FLOAT_EQ(-1.0f, buffer.at(age, 3, -1.0f)) << "age " << age;
  }

  buffer.clear();
  EXPECT_EQ(0, buffer.size());
  appendNumbered(buffer, 9, 1, 2);
  EXPECT_EQ(1, buffer.size());
  EXPECT_FLOAT_EQ(901.0f, buffer.at(0, 2, -1.0f));
}

TEST(CostRingBuffer, MemoryIsKTimesNFloatsWhateverWasAppended)
{
  // K = 20, N = 1788 (Nordland): 20 * 1788 * 4 bytes = 143040.
  arl::CostRingBuffer buffer(20, 1788);
  EXPECT_EQ(143040u, buffer.memoryBytes());
  for (int r = 0; r < 5000; ++r)
    buffer.appendRow(r % 1700, (r % 7 == 0) ? 1788 - r % 1700 : 81);
  EXPECT_EQ(143040u, buffer.memoryBytes());
  EXPECT_EQ(20, buffer.size());
  buffer.resize(10, 300);  // 10 * 300 * 4
  EXPECT_EQ(12000u, buffer.memoryBytes());
}

TEST(CostRingBuffer, RepeatedQueryFlagFollowsTheRowsThroughWrapAndResize)
{
  // K = 3, N = 4. Rows r = 0..4 with repeated_query = 0 1 1 0 1 (r = 1, 2, 4 flagged) and values
  // 100 * r + offset. After 5 appends rows 2, 3, 4 remain: age 0 = row 4 (T), 1 = row 3 (F), 2 = row 2 (T).
  const bool flags[5] = { false, true, true, false, true };
  arl::CostRingBuffer buffer(3, 4);
  for (int r = 0; r < 5; ++r)
  {
    float* row = buffer.appendRow(0, 4, flags[r]);
    for (int j = 0; j < 4; ++j)
      row[j] = 100.0f * r + j;
    EXPECT_EQ(flags[r], buffer.repeatedQuery(0)) << "after row " << r;
  }
  for (int age = 0; age < 3; ++age)
  {
    EXPECT_EQ(flags[4 - age], buffer.repeatedQuery(age)) << "age " << age;
    EXPECT_FLOAT_EQ(100.0f * (4 - age), buffer.row(age)[0]) << "age " << age;
  }
  // Distinct views in the newest 3 / 2 / 1 rows (T F T, newest first): a flagged row adds none unless it
  // is the window's oldest: 0 + 1 + 1 = 2; 0 + 1 = 1; the single row always counts: 1.
  EXPECT_EQ(2, buffer.distinctViews(3));
  EXPECT_EQ(1, buffer.distinctViews(2));
  EXPECT_EQ(1, buffer.distinctViews(1));

  // Row 5 lands in the slot row 2 (T) used, with the default flag: false, not the stale true.
  // Ages: 0 = row 5 (F), 1 = row 4 (T), 2 = row 3 (F).
  float* row5 = buffer.appendRow(0, 4);
  for (int j = 0; j < 4; ++j)
    row5[j] = 500.0f + j;
  EXPECT_FALSE(buffer.repeatedQuery(0));
  EXPECT_TRUE(buffer.repeatedQuery(1));
  EXPECT_FALSE(buffer.repeatedQuery(2));

  // Shrink to K = 2: rows 5 (F) and 4 (T) kept at ages 0 and 1.
  buffer.resize(2, 4);
  ASSERT_EQ(2, buffer.size());
  EXPECT_FALSE(buffer.repeatedQuery(0));
  EXPECT_TRUE(buffer.repeatedQuery(1));
  EXPECT_FLOAT_EQ(400.0f, buffer.row(1)[0]);

  // Grow to K = 5 and narrow to N = 2 (re-packed into new slots): same flags per age; then append
  // row 6 (T): ages 0 = row 6 (T), 1 = row 5 (F), 2 = row 4 (T).
  buffer.resize(5, 2);
  ASSERT_EQ(2, buffer.size());
  EXPECT_FALSE(buffer.repeatedQuery(0));
  EXPECT_TRUE(buffer.repeatedQuery(1));
  float* row6 = buffer.appendRow(0, 2, true);
  row6[0] = 600.0f;
  row6[1] = 601.0f;
  ASSERT_EQ(3, buffer.size());
  EXPECT_TRUE(buffer.repeatedQuery(0));
  EXPECT_FALSE(buffer.repeatedQuery(1));
  EXPECT_TRUE(buffer.repeatedQuery(2));
  EXPECT_FLOAT_EQ(501.0f, buffer.at(1, 1, -1.0f));
  EXPECT_FLOAT_EQ(401.0f, buffer.at(2, 1, -1.0f));

  // Wrap the grown buffer: rows 7..10 with flags F F T F; K = 5 keeps rows 6..10:
  // ages 0..4 = rows 10 (F), 9 (T), 8 (F), 7 (F), 6 (T).
  const bool later[4] = { false, false, true, false };
  for (int r = 7; r <= 10; ++r)
    buffer.appendRow(0, 2, later[r - 7])[0] = 100.0f * r;
  ASSERT_EQ(5, buffer.size());
  const bool expected[5] = { false, true, false, false, true };
  for (int age = 0; age < 5; ++age)
  {
    EXPECT_EQ(expected[age], buffer.repeatedQuery(age)) << "age " << age;
    EXPECT_FLOAT_EQ(100.0f * (10 - age), buffer.row(age)[0]) << "age " << age;
  }
}
