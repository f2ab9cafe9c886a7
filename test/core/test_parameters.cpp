// Parameters by name (parameters.h): the params.yaml reader and the split of names between the
// preprocessor and the localizer.
#include <cstdio>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/parameters.h"

namespace arl = along_route_localization;

namespace
{

class ParameterFile : public ::testing::Test
{
protected:
  void TearDown() override { std::remove(path_.c_str()); }

  /// Writes `text` as the file and loads it over default parameters; "" when it loads.
  std::string load(const std::string& text)
  {
    std::ofstream(path_) << text;
    preprocessing_ = arl::PreprocessingParams();
    localizer_ = arl::LocalizerParams();
    std::string error;
    return arl::loadParameterFile(path_, &preprocessing_, &localizer_, &error) ? "" : error;
  }

  const std::string path_ = ::testing::TempDir() + "along_route_params_test.yaml";
  arl::PreprocessingParams preprocessing_;
  arl::LocalizerParams localizer_;
};

TEST_F(ParameterFile, BooleansInEveryFormRosparamReads)
{
  // The default is true: each form of false turns it off; each form of true turns a false one on.
  ASSERT_TRUE(arl::LocalizerParams().subpixel_shift);
  for (const char* no : { "false", "False", "no", "No", "off", "OFF", "0" })
  {
    EXPECT_EQ("", load(std::string("subpixel_shift: ") + no + "\n")) << no;
    EXPECT_FALSE(localizer_.subpixel_shift) << no;
  }
  for (const char* yes : { "true", "yes", "Yes", "on", "1" })
  {
    arl::PreprocessingParams preprocessing;
    arl::LocalizerParams localizer;
    localizer.run_dead_reckoning = false;
    std::string error;
    EXPECT_TRUE(arl::applyParameter("run_dead_reckoning", yes, &preprocessing, &localizer, &error)) << error;
    EXPECT_TRUE(localizer.run_dead_reckoning) << yes;
  }
  EXPECT_NE(std::string::npos, load("parallel: maybe\n").find("'maybe'"));
}

TEST_F(ParameterFile, ANameGivenTwiceIsAnErrorNamingBothLines)
{
  const std::string error = load("max_step: 3\n# comment\nlocalizer:\n  max_step: 4\n");
  EXPECT_NE(std::string::npos, error.find(path_ + ":4:")) << error;
  EXPECT_NE(std::string::npos, error.find("'max_step' is already set on line 1")) << error;
  // Once each, in different sections, loads.
  EXPECT_EQ("", load("preprocessor:\n  sky_fraction: 0.25\nlocalizer:\n  max_step: 3\n"));
  EXPECT_EQ(3, localizer_.dtw.max_step);
  EXPECT_DOUBLE_EQ(0.25, preprocessing_.sky_fraction);
  // The recorder's section is skipped, so its names do not count.
  EXPECT_EQ("", load("map_recorder:\n  every_nth: 3\n  every_nth: 4\nmax_step: 2\n"));
}

TEST_F(ParameterFile, EntriesAreReadWithTheirLinesAndAppliedLater)
{
  // The launch files' params_file as it is: sections, comments, the recorder's section skipped.
  std::ofstream(path_) << "# tuned on the yard\npreprocessor:\n  sky_fraction: 0.25  # trees\nmap_recorder:\n"
                          "  every_nth: 3\nlocalizer:\n  max_step: 3\nbogus_name: 1\n";
  std::vector<arl::ParameterEntry> entries;
  std::string error;
  ASSERT_TRUE(arl::readParameterFile(path_, &entries, &error)) << error;
  ASSERT_EQ(3u, entries.size());
  EXPECT_EQ("sky_fraction", entries[0].name);
  EXPECT_EQ("0.25", entries[0].value);
  EXPECT_EQ(3, entries[0].line);
  EXPECT_EQ("max_step", entries[1].name);
  EXPECT_EQ(7, entries[1].line);
  EXPECT_EQ("bogus_name", entries[2].name);
  EXPECT_EQ(8, entries[2].line);
  // Reading does not judge names; applying does, naming the line, after applying the entries before it.
  arl::PreprocessingParams preprocessing;
  arl::LocalizerParams localizer;
  EXPECT_FALSE(arl::applyParameterEntries(path_, entries, &preprocessing, &localizer, &error));
  EXPECT_NE(std::string::npos, error.find(path_ + ":8:")) << error;
  EXPECT_EQ(3, localizer.dtw.max_step);
  // The same entries apply to other parameters without reading the file again.
  std::remove(path_.c_str());
  entries.pop_back();
  arl::PreprocessingParams other;
  other.sky_fraction = 0.5;
  ASSERT_TRUE(arl::applyParameterEntries(path_, entries, &other, &localizer, &error)) << error;
  EXPECT_DOUBLE_EQ(0.25, other.sky_fraction);
  // A line that is not "name: value" is a read error.
  std::ofstream(path_) << "max_step 3\n";
  EXPECT_FALSE(arl::readParameterFile(path_, &entries, &error));
  EXPECT_NE(std::string::npos, error.find(path_ + ":1: expected 'name: value'")) << error;
}

TEST(ParameterNames, EachNameSetsAFieldOfItsOwnGroupOnly)
{
  // A name is the preprocessor's exactly when setting it changes PreprocessingParams; checked by
  // setting every name to a value other than its default.
  const std::set<std::string> preprocessing_names = [] {
    const auto names = arl::preprocessingParameterNames();
    return std::set<std::string>(names.begin(), names.end());
  }();
  const auto localizer_names = arl::localizerParameterNames();
  EXPECT_EQ(arl::parameterNames().size(), preprocessing_names.size() + localizer_names.size());
  EXPECT_TRUE(preprocessing_names.count("normalization_strength"));
  EXPECT_TRUE(preprocessing_names.count("sky_fraction"));
  for (const std::string& name : arl::parameterNames())
  {
    std::string error;
    // Some of these parse for every name, and for each preprocessing name one differs from its default.
    bool changed_preprocessing = false, parsed = false;
    for (const char* value : { "7", "3", "patch", "census", "seqslam", "false", "true" })
    {
      arl::PreprocessingParams p;
      arl::LocalizerParams l;
      if (!arl::applyParameter(name, value, &p, &l, &error))
        continue;
      parsed = true;
      // Compared field by field: operator== ignores the fields the normalization does not read.
      changed_preprocessing = changed_preprocessing || p.serialize() != arl::PreprocessingParams().serialize();
    }
    EXPECT_TRUE(parsed) << name;
    EXPECT_EQ(changed_preprocessing, preprocessing_names.count(name) == 1) << name;
  }
}

}  // namespace
