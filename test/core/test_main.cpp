// Entry point of the core gtest suite (catkin_add_gtest does not link gtest_main).
#include <gtest/gtest.h>

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
