// Parameters by name (parameters.h): the parameter table, the params.yaml reader and the split of names
// between the preprocessor and the localizer.
#include <algorithm>
#include <cmath>
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

  /// Writes `text` as the file and applies it as localize_offline --params does (applyParameterEntriesChecked)
  /// over the parameters as they are; its warnings, and the entries read for a test that applies them again.
  ::testing::AssertionResult applyChecked(const std::string& text, std::vector<std::string>* warnings,
                                          std::vector<arl::ParameterEntry>* entries_read = nullptr)
  {
    std::ofstream(path_) << text;
    std::vector<arl::ParameterEntry> entries;
    std::string error;
    if (!arl::readParameterFile(path_, &entries, &error) ||
        !arl::applyParameterEntriesChecked(path_, entries, &preprocessing_, &localizer_, warnings, &error))
      return ::testing::AssertionFailure() << error;
    if (entries_read)
      *entries_read = entries;
    return ::testing::AssertionSuccess();
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
  // --set and the strict loader name the parameter a misspelling is close to, as the checked path does.
  arl::PreprocessingParams preprocessing;
  arl::LocalizerParams localizer;
  std::string error;
  EXPECT_FALSE(arl::applyParameter("ring_bufer_rows", "20", &preprocessing, &localizer, &error));
  EXPECT_EQ("unknown parameter 'ring_bufer_rows' (did you mean ring_buffer_rows?)", error);
  EXPECT_FALSE(arl::applyParameter("no_such_parameter", "1", &preprocessing, &localizer, &error));
  EXPECT_EQ("unknown parameter 'no_such_parameter'", error);
  EXPECT_FALSE(arl::applyParameter("homing_gain", "3", &preprocessing, &localizer, &error));  // the follower's
  EXPECT_EQ("unknown parameter 'homing_gain'", error);
  // Close only to a follower's name, which --set would refuse too: no suggestion there, one in a params file.
  EXPECT_FALSE(arl::applyParameter("slow_factr", "0.5", &preprocessing, &localizer, &error));
  EXPECT_EQ("unknown parameter 'slow_factr'", error);
  EXPECT_EQ(" (did you mean slow_factor?)", arl::didYouMean("slow_factr"));
}

TEST(ParameterFileRead, AFolderIsRefusedAsUnreadable)
{
  // A folder opens as a stream on Linux, then every read fails: it was taken as an empty file and the
  // run went on with the defaults.
  std::vector<arl::ParameterEntry> entries;
  std::string error;
  EXPECT_FALSE(arl::readParameterFile(::testing::TempDir(), &entries, &error));
  EXPECT_EQ("cannot read parameter file '" + ::testing::TempDir() + "' (a folder, or a read error)", error);
  EXPECT_TRUE(entries.empty());
}

TEST_F(ParameterFile, ANameGivenTwiceIsAnErrorNamingBothLines)
{
  const std::string error = load("max_step: 3\n# comment\nmax_step: 4\n");
  EXPECT_NE(std::string::npos, error.find(path_ + ":3:")) << error;
  EXPECT_NE(std::string::npos, error.find("'max_step' is already set on line 1")) << error;
  // Once each, in different sections, loads.
  EXPECT_EQ("", load("preprocessor:\n  sky_fraction: 0.25\nlocalizer:\n  max_step: 3\n"));
  EXPECT_EQ(3, localizer_.dtw.max_step);
  EXPECT_DOUBLE_EQ(0.25, preprocessing_.sky_fraction);
  // The recorder's section is skipped, so its names do not count.
  EXPECT_EQ("", load("map_recorder:\n  every_nth: 3\n  every_nth: 4\nlocalizer:\n  max_step: 2\n"));
  // So is the route follower's (follow.launch's params_file), and a section after it is read again.
  EXPECT_EQ("", load("route_follower:\n  homing_gain: 3.0\n  homing_gain: 2.0\nlocalizer:\n  max_step: 4\n"));
  EXPECT_EQ(4, localizer_.dtw.max_step);
  // Outside its section, a follower's parameter is not the localizer's: refused, naming it.
  EXPECT_EQ(path_ + ":1: unknown parameter 'homing_gain'", load("homing_gain: 3.0\n"));
  // Under the preprocessor's section, the localizer's parameter is set where its nodelet does not read it.
  EXPECT_EQ(path_ + ":2: 'max_step' is the localizer's parameter but is under preprocessor:, where the launch files "
                    "set it for the preprocessor, which does not read it: move it under localizer:",
            load("preprocessor:\n  max_step: 3\n"));
}

TEST_F(ParameterFile, EveryNodeletsSectionIsCheckedAsItsNodeletReadsItAndOnlyTheLocalizingOnesApplied)
{
  // The launch files' params_file with a mistake in each section, and each nodelet's own settings.
  localizer_.dtw.max_step = 2;
  std::vector<std::string> warnings;
  ASSERT_TRUE(applyChecked("preprocessor:\n"          // 1
                           "  sky_fraction: 0.25\n"    // 2
                           "  max_step: 3\n"           // 3: the localizer's, misplaced
                           "  queue_size: 4\n"         // 4: the preprocessor nodelet's own setting: fine
                           "map_recorder:\n"           // 5
                           "  every_nth: 0\n"          // 6: below 1
                           "  autostart: true\n"       // 7: the recorder nodelet's own setting
                           "  homing_gain: 2\n"        // 8: the follower's, misplaced
                           "localizer:\n"              // 9
                           "  ring_buffer_rows: 12\n"  // 10
                           "route_follower:\n"         // 11
                           "  homing_gain: 1.5\n"      // 12: once per section is not twice
                           "  speed_factr: 0.5\n"      // 13: misspelt
                           "  max_linear_decel: 0.01\n"  // 14: below 0.1
                           "  control_rate: 20\n"      // 15: the follower nodelet's own setting
                           "  every_nth: 2\n",         // 16: the recorder's, misplaced
                           &warnings));
  const std::string at = path_ + ":";
  const std::vector<std::string> expected = {
    at + "3: 'max_step' is the localizer's parameter but is under preprocessor:, where the launch files set it for "
         "the preprocessor, which does not read it: move it under localizer:; ignored",
    at + "6: every_nth 0 is outside 1 .. 1000 frames; using 1",
    at + "8: 'homing_gain' is the route_follower's parameter but is under map_recorder:, where the launch files set "
         "it for the map_recorder, which does not read it: move it under route_follower:; ignored",
    at + "13: unknown parameter 'speed_factr' refused (did you mean speed_factor?)",
    at + "14: max_linear_decel 0.01 is outside 0.1 .. 100 m/s^2; using 0.1",
    at + "16: 'every_nth' is the map_recorder's parameter but is under route_follower:, where the launch files set "
         "it for the route_follower, which does not read it: move it under map_recorder:; ignored",
  };
  EXPECT_EQ(expected, warnings);
  // Only the preprocessor's and the localizer's entries in their own sections were applied.
  EXPECT_DOUBLE_EQ(0.25, preprocessing_.sky_fraction);
  EXPECT_EQ(12, localizer_.ring_buffer_rows);
  EXPECT_EQ(2, localizer_.dtw.max_step);
  // A name twice in one of those sections is still an error.
  EXPECT_FALSE(applyChecked("route_follower:\n  homing_gain: 1.5\n  homing_gain: 2\n", &warnings));
}

TEST_F(ParameterFile, EntriesAreReadWithTheirLinesAndAppliedLater)
{
  // The launch files' params_file as it is: sections, comments, the recorder's section skipped.
  std::ofstream(path_) << "# tuned on the yard\npreprocessor:\n  sky_fraction: 0.25  # trees\nmap_recorder:\n"
                          "  every_nth: 3\nlocalizer:\n  max_step: 3\n  bogus_name: 1\n";
  std::vector<arl::ParameterEntry> entries;
  std::string error;
  ASSERT_TRUE(arl::readParameterFile(path_, &entries, &error)) << error;
  ASSERT_EQ(4u, entries.size());
  EXPECT_EQ("sky_fraction", entries[0].name);
  EXPECT_EQ("0.25", entries[0].value);
  EXPECT_EQ(3, entries[0].line);
  EXPECT_EQ("preprocessor", entries[0].section);
  EXPECT_EQ("every_nth", entries[1].name);
  EXPECT_EQ("map_recorder", entries[1].section);
  EXPECT_EQ("max_step", entries[2].name);
  EXPECT_EQ(7, entries[2].line);
  EXPECT_EQ("localizer", entries[2].section);
  EXPECT_EQ("bogus_name", entries[3].name);
  EXPECT_EQ(8, entries[3].line);
  // Reading does not judge names; applying does, naming the line, after applying the entries before it
  // (the recorder's section is not the localizer's: skipped).
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

TEST_F(ParameterFile, WhatTheLaunchFilesYamlWouldReadOtherwiseIsAnErrorNamingTheLine)
{
  // A misspelt section: rosparam loads it where no nodelet reads it, and the line reader took its entries
  // as the localizer's.
  EXPECT_EQ(path_ + ":1: 'localiser:' has no value and is not a section the launch files read (preprocessor:, "
                    "localizer:, map_recorder:, route_follower:, each at the start of a line)",
            load("localiser:\n  ring_buffer_rows: 10\n"));
  // Flow style: rosparam reads the values, the line reader saw an unknown parameter 'localizer'.
  EXPECT_EQ(path_ + ":2: 'localizer: {ring_buffer_rows: 10, max_step: 3}' is YAML's flow style, not read here: "
                    "write one 'name: value' per line under 'localizer:'",
            load("# tuned\nlocalizer: {ring_buffer_rows: 10, max_step: 3}\n"));
  // Indentation YAML refuses: rosparam (and so roslaunch) refuses the file.
  EXPECT_EQ(path_ + ":3: 'max_step' is indented by 3 spaces, the entries above it by 2 (YAML refuses that)",
            load("localizer:\n  ring_buffer_rows: 10\n   max_step: 3\n"));
  EXPECT_EQ(path_ + ":1: 'max_step' is indented but under no section: indent entries only under preprocessor:, "
                    "localizer:, map_recorder: or route_follower:",
            load("  max_step: 3\n"));
  // An entry at the start of a line beside sections: YAML puts it under no section (no nodelet reads it),
  // before a section or after one; and a section given twice, of which YAML keeps the last.
  const std::string flat = "' is at the start of a line in a file with sections: YAML (the launch files) reads it "
                           "as no section's, which no nodelet reads; indent it under its section (or give no "
                           "section at all)";
  EXPECT_EQ(path_ + ":3: 'ring_buffer_rows" + flat, load("localizer:\n  max_step: 3\nring_buffer_rows: 12\n"));
  EXPECT_EQ(path_ + ":2: 'ring_buffer_rows" + flat, load("# tuned\nring_buffer_rows: 12\nlocalizer:\n  max_step: 3\n"));
  EXPECT_EQ(path_ + ":3: 'localizer:' appears a second time (YAML keeps only the last one): give each section once",
            load("localizer:\n  max_step: 3\nlocalizer:\n  ring_buffer_rows: 12\n"));
  // A byte-order mark before the first header, as some editors write: YAML skips it, and so does the reader.
  EXPECT_EQ("", load("\xEF\xBB\xBFlocalizer:\n  max_step: 3\n"));
  EXPECT_EQ(3, localizer_.dtw.max_step);
  EXPECT_EQ(path_ + ":2: a tab in the indentation (YAML, which the launch files read the file as, allows spaces only)",
            load("localizer:\n\tmax_step: 3\n"));
  // Each section sets its own indentation; a flat file (no section anywhere) reads as before.
  EXPECT_EQ("", load("preprocessor:\n    sky_fraction: 0.25\nlocalizer:\n  max_step: 3\n"));
  EXPECT_EQ(3, localizer_.dtw.max_step);
  EXPECT_DOUBLE_EQ(0.25, preprocessing_.sky_fraction);
  EXPECT_EQ("", load("max_step: 4\nring_buffer_rows: 12\n"));
  EXPECT_EQ(4, localizer_.dtw.max_step);
  EXPECT_EQ(12, localizer_.ring_buffer_rows);
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

TEST(ParameterTable, EachDefaultIsTheFieldsInitializerAndLiesInItsRange)
{
  // One default for each value: the table reads it from the structs, and DtwParams is the localizer's.
  EXPECT_EQ("30", arl::findParameter("ring_buffer_rows")->defaultText());
  EXPECT_EQ("0.85", arl::findParameter("skip_penalty")->defaultText());
  EXPECT_FLOAT_EQ(0.85f, arl::DtwParams().skip_penalty);  // was 1.0 here and 0.85 in the localizer
  EXPECT_FLOAT_EQ(arl::DtwParams().skip_penalty, arl::LocalizerParams().dtw.skip_penalty);
  EXPECT_FLOAT_EQ(arl::DtwParams().first_stop_penalty, arl::LocalizerParams().dtw.first_stop_penalty);
  EXPECT_FLOAT_EQ(arl::DtwParams().sustained_skip_penalty, arl::LocalizerParams().dtw.sustained_skip_penalty);
  EXPECT_EQ("57.2958", arl::findParameter("horizontal_fov_deg")->defaultText());  // 1 rad
  const arl::ParameterSet defaults;
  std::set<std::string> names;
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    EXPECT_TRUE(names.insert(spec.name).second) << spec.name << " is in the table twice";
    EXPECT_FALSE(spec.doc.empty()) << spec.name;
    if (spec.type == arl::ParameterType::kChoice)
      EXPECT_NE(spec.choices.end(), std::find(spec.choices.begin(), spec.choices.end(), spec.defaultText()))
          << spec.name;
    else
      EXPECT_TRUE(spec.inRange(spec.get_number(defaults))) << spec.name << " = " << spec.defaultText();
  }
  EXPECT_EQ("", defaults.localizer.validate());
  EXPECT_EQ("", defaults.preprocessing.validate());
  EXPECT_EQ("", defaults.follower.validate());
  // The route follower's defaults are RouteFollowerParams' initializers, read by the name users give.
  EXPECT_EQ("0.5", arl::findParameter("max_homing_turn_rate")->defaultText());
  EXPECT_EQ("0.3", arl::findParameter("homing_time_constant")->defaultText());
  EXPECT_EQ("1", arl::findParameter("watchdog_timeout")->defaultText());
  EXPECT_EQ("8", arl::findParameter("stop_after_frames")->defaultText());
}

TEST(ParameterTable, ValidateRefusesEveryNumberOutsideItsTableRange)
{
  // One below the least and one above the most value of each number, every other parameter at its
  // default: validate() names that parameter and its range.
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    if (spec.group == arl::ParameterGroup::kMapRecorder || spec.type == arl::ParameterType::kChoice ||
        spec.type == arl::ParameterType::kBool)
      continue;
    const double step = spec.type == arl::ParameterType::kInt ? 1.0 : std::max(1e-3, (spec.max - spec.min) * 1e-3);
    for (const double value : { spec.min - step, spec.max + step })
    {
      arl::ParameterSet params;
      spec.set_number(&params, value);
      const std::string error = spec.group == arl::ParameterGroup::kLocalizer     ? params.localizer.validate() :
                                spec.group == arl::ParameterGroup::kRouteFollower ? params.follower.validate() :
                                                                                    params.preprocessing.validate();
      EXPECT_EQ(0u, error.find(spec.name + " must be in " + spec.rangeText())) << spec.name << " " << value << ": "
                                                                              << error;
    }
  }
  // The window's least: 3 rows, and no fewer than min_init_frames, which a global search needs before it
  // answers. Nordland winter drive against the summer map (1788 frames), with min_init_frames 5: K = 1,
  // 2 or 4 tracked the first 22 frames and reported lost on all the others; K = 5 tracked 1711, K = 30
  // 1785. With min_init_frames 3, K = 3 tracked 656 (within one keyframe 57%, against 99% with K = 30).
  arl::LocalizerParams params;
  params.ring_buffer_rows = 2;
  EXPECT_EQ("ring_buffer_rows must be in 3 .. 1000 frames, got 2", params.validate());
  params.ring_buffer_rows = 4;
  EXPECT_EQ("ring_buffer_rows (4) must be at least min_init_frames (5): a global search would never answer",
            params.validate());
  params.min_init_frames = 4;
  EXPECT_EQ("", params.validate());
}

TEST(ParameterTable, ValidateTakesEveryNumberAtEitherEndOfItsTableRange)
{
  // A float field holds the nearest float to a bound given exactly (row_weight_range 0.99 is stored as
  // 0.9900000095): validate() refused the documented most ("must be in 0 .. 0.99, got 0.99"). At its least
  // and its most, every other parameter at its default, no number is out of its range (a rule between
  // two parameters may still object: lost_after_frames 10000 is more than lost_window_frames 8).
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    if (spec.group == arl::ParameterGroup::kMapRecorder || spec.type == arl::ParameterType::kChoice ||
        spec.type == arl::ParameterType::kBool)
      continue;
    for (const double value : { spec.min, spec.max })
    {
      arl::ParameterSet params;
      spec.set_number(&params, value);
      const std::string error = spec.group == arl::ParameterGroup::kLocalizer     ? params.localizer.validate() :
                                spec.group == arl::ParameterGroup::kRouteFollower ? params.follower.validate() :
                                                                                    params.preprocessing.validate();
      EXPECT_EQ(std::string::npos, error.find(spec.name + " must be in " + spec.rangeText()))
          << spec.name << " " << value << ": " << error;
    }
  }
  arl::ParameterSet params;
  EXPECT_EQ("", arl::setParameterChecked("row_weight_range", "0.99", &params));
  EXPECT_EQ("", params.localizer.validate());
}

TEST(ParameterTable, CheckedValuesAreCorrectedIntoTheRangeOrRefusedByName)
{
  arl::ParameterSet params;
  bool refused = true;
  // dynparam's -3 for K (clamped to 1 without a word before, and lost for the rest of the bag).
  EXPECT_EQ("ring_buffer_rows -3 is outside 3 .. 1000 frames; using 3",
            arl::setParameterChecked("ring_buffer_rows", "-3", &params, &refused));
  EXPECT_FALSE(refused);
  EXPECT_EQ(3, params.localizer.ring_buffer_rows);
  EXPECT_EQ("ring_buffer_rows 5000 is outside 3 .. 1000 frames; using 1000",
            arl::setParameterChecked("ring_buffer_rows", "5000", &params));
  EXPECT_EQ(1000, params.localizer.ring_buffer_rows);
  EXPECT_EQ("", arl::setParameterChecked("ring_buffer_rows", "10", &params, &refused));
  EXPECT_EQ(10, params.localizer.ring_buffer_rows);
  EXPECT_EQ("sky_fraction 1.5 is outside 0 .. 0.95; using 0.95", arl::setParameterChecked("sky_fraction", "1.5", &params));
  EXPECT_DOUBLE_EQ(0.95, params.preprocessing.sky_fraction);
  // A stop is bounded: with max_linear_decel 0.001 (taken before) ~stop left a robot at 1 m/s for 1000 s.
  EXPECT_EQ("max_linear_decel 0.001 is outside 0.1 .. 100 m/s^2; using 0.1",
            arl::setParameterChecked("max_linear_decel", "0.001", &params));
  EXPECT_DOUBLE_EQ(0.1, params.follower.max_linear_decel);
  EXPECT_EQ("max_angular_accel 0.01 is outside 0.1 .. 100 rad/s^2; using 0.1",
            arl::setParameterChecked("max_angular_accel", "0.01", &params));
  // Refused: the value stays what it was.
  EXPECT_EQ("method 'DTW' is not one of dtw | seqslam; keeping dtw",
            arl::setParameterChecked("method", "DTW", &params, &refused));
  EXPECT_TRUE(refused);
  EXPECT_EQ(arl::SequenceMethod::kOnlineDtw, params.localizer.method);
  EXPECT_EQ("max_step '2.5' is not an integer in 1 .. 16 keyframes per frame; keeping 2",
            arl::setParameterChecked("max_step", "2.5", &params));
  EXPECT_EQ("parallel 'maybe' is not true or false; keeping true", arl::setParameterChecked("parallel", "maybe", &params));
  EXPECT_EQ("unknown parameter 'ring_bufer_rows' refused (did you mean ring_buffer_rows?)",
            arl::setParameterChecked("ring_bufer_rows", "10", &params, &refused));
  EXPECT_TRUE(refused);
  EXPECT_EQ(10, params.localizer.ring_buffer_rows);
  EXPECT_EQ("horizontal_fov_deg 180 is outside 1 .. 179 deg; using 179",
            arl::setParameterChecked("horizontal_fov_deg", "180", &params));
  EXPECT_NEAR(179.0 * M_PI / 180.0, params.localizer.horizontal_fov_rad, 1e-12);
}

TEST_F(ParameterFile, OneBadValueIsRefusedByNameAndTheGoodOnesAreUsed)
{
  // Before, "method: DTW" rejected the whole file and the defaults were used instead of K = 10, s = 3.
  std::vector<arl::ParameterEntry> entries;
  std::vector<std::string> warnings;
  ASSERT_TRUE(applyChecked("localizer:\n  ring_buffer_rows: 10\n  method: DTW\n  max_step: 3\n  max_shift_px: 500\n"
                           "  ring_bufer_rows: 9\npreprocessor:\n  sky_fraction: 0.25\n",
                           &warnings, &entries));
  EXPECT_EQ(10, localizer_.ring_buffer_rows);
  EXPECT_EQ(3, localizer_.dtw.max_step);
  EXPECT_EQ(arl::SequenceMethod::kOnlineDtw, localizer_.method);
  EXPECT_EQ(127, localizer_.max_shift_px);
  EXPECT_DOUBLE_EQ(0.25, preprocessing_.sky_fraction);
  ASSERT_EQ(3u, warnings.size());
  EXPECT_EQ(path_ + ":3: method 'DTW' is not one of dtw | seqslam; keeping dtw", warnings[0]);
  EXPECT_EQ(path_ + ":5: max_shift_px 500 is outside 0 .. 127 px; using 127", warnings[1]);
  EXPECT_EQ(path_ + ":6: unknown parameter 'ring_bufer_rows' refused (did you mean ring_buffer_rows?)", warnings[2]);
  // A name given twice is still an error: which value was meant is unknown.
  entries.push_back({ "max_step", "4", 9, "localizer" });
  std::string error;
  EXPECT_FALSE(arl::applyParameterEntriesChecked(path_, entries, &preprocessing_, &localizer_, &warnings, &error));
  EXPECT_NE(std::string::npos, error.find("'max_step' is already set on line 4")) << error;
}

// The preprocessor nodelet corrects an even filter_window and a patch_size that does not divide the image
// from a launch file's parameter file; a parameter file given to localize_offline refused them (the same file).
TEST_F(ParameterFile, CombinationsAreCorrectedAsTheNodeletCorrectsThem)
{
  std::vector<std::string> warnings;
  ASSERT_TRUE(applyChecked("preprocessor:\n  filter_window: 8\n  normalization: patch\n  output_width: 48\n"
                           "  output_height: 36\n  patch_size: 8\n",
                           &warnings));
  EXPECT_EQ(9, preprocessing_.filter_window);
  EXPECT_EQ(6, preprocessing_.patch_size);  // 48 and 36 have the common divisors 1, 2, 3, 4, 6, 12
  EXPECT_EQ("", preprocessing_.validate());
  ASSERT_EQ(2u, warnings.size());
  EXPECT_EQ(path_ + ": filter_window 8 is even; using 9", warnings[0]);
  EXPECT_EQ(path_ + ": patch_size 8 does not divide the output size 48x36; using 6", warnings[1]);
  // divisive normalization: the patch size is not used, so not corrected
  arl::PreprocessingParams divisive;
  divisive.output_width = 48;
  divisive.output_height = 36;
  EXPECT_TRUE(divisive.correctCombinations().empty());
  EXPECT_EQ(8, divisive.patch_size);
  // 65x48 have no common divisor but 1, below patch_size's least (2): not corrected, refused by validate()
  arl::PreprocessingParams coprime = divisive;
  coprime.normalization = arl::NormalizationMethod::kPatch;
  coprime.output_width = 65;
  coprime.output_height = 48;
  EXPECT_TRUE(coprime.correctCombinations().empty());
  EXPECT_EQ(8, coprime.patch_size);
  EXPECT_NE(std::string::npos, coprime.validate().find("patch_size must divide")) << coprime.validate();
}

TEST(ParameterTable, HelpShowsEachParameterWithDefaultRangeUnitAndMeaning)
{
  const std::string help = arl::parameterHelp({ arl::ParameterGroup::kPreprocessor, arl::ParameterGroup::kLocalizer },
                                              true);
  EXPECT_NE(std::string::npos,
            help.find("    ring_buffer_rows = 30  (3 .. 1000 frames)\n        K: frames in the sequence window"))
      << help;
  EXPECT_NE(std::string::npos, help.find("    method = dtw  (dtw | seqslam)\n")) << help;
  EXPECT_NE(std::string::npos, help.find("    subpixel_shift = true  (true | false)\n")) << help;
  EXPECT_EQ(std::string::npos, help.find("every_nth")) << "the recorder's parameters are not asked for";
  for (const std::string& name : arl::parameterNames())
    EXPECT_NE(std::string::npos, help.find("    " + name + " = ")) << name;
}

// The user tier (ParameterTier): what a user sets for the robot and the route. Named here row by row, in
// table order, so that a row moving between tiers is a deliberate change of this test (issue 30, item 5:
// about a dozen for the localizer).
TEST(ParameterTiers, TheUserTierIsTheseRowsAndEveryOtherIsAdvanced)
{
  using Names = std::vector<std::string>;
  const Names preprocessor = { "output_width", "output_height", "normalization", "filter_window",
                               "normalization_strength", "sky_fraction" };
  const Names localizer = { "method",
                            "ring_buffer_rows",              // K
                            "max_step",                      // s
                            "max_shift_px",                  // m
                            "homing_max_shift_px",
                            "homing_max_vertical_shift_px",
                            "contrast_window",               // n
                            "search_radius",
                            "confidence_threshold",
                            "horizontal_fov_deg",
                            "fill_frame_gaps",
                            "start_keyframe",
                            "detect_kidnapping",
                            "end_of_route_keyframes" };
  const Names recorder = { "every_nth", "min_time_gap", "min_appearance_change", "min_distance" };
  const Names follower = { "homing_gain",       "max_homing_turn_rate", "speed_factor",     "min_confidence",
                           "recovery_distance", "watchdog_timeout",     "max_linear_accel", "max_linear_decel",
                           "max_angular_accel" };
  EXPECT_EQ(preprocessor, arl::parameterNamesOf(arl::ParameterGroup::kPreprocessor, arl::ParameterTier::kUser));
  EXPECT_EQ(localizer, arl::parameterNamesOf(arl::ParameterGroup::kLocalizer, arl::ParameterTier::kUser));
  EXPECT_EQ(recorder, arl::parameterNamesOf(arl::ParameterGroup::kMapRecorder, arl::ParameterTier::kUser));
  EXPECT_EQ(follower, arl::parameterNamesOf(arl::ParameterGroup::kRouteFollower, arl::ParameterTier::kUser));
  EXPECT_LE(localizer.size(), 15u);
  // The rest of the 84 rows (9 + 58 + 4 + 13) is advanced: 3 of the preprocessor, 44 of the localizer,
  // none of the recorder, 4 of the follower.
  EXPECT_EQ(84u, arl::parameterTable().size());
  EXPECT_EQ(3u, arl::parameterNamesOf(arl::ParameterGroup::kPreprocessor, arl::ParameterTier::kAdvanced).size());
  EXPECT_EQ(44u, arl::parameterNamesOf(arl::ParameterGroup::kLocalizer, arl::ParameterTier::kAdvanced).size());
  EXPECT_EQ(0u, arl::parameterNamesOf(arl::ParameterGroup::kMapRecorder, arl::ParameterTier::kAdvanced).size());
  EXPECT_EQ((Names{ "homing_time_constant", "slow_after_frames", "stop_after_frames", "slow_factor" }),
            arl::parameterNamesOf(arl::ParameterGroup::kRouteFollower, arl::ParameterTier::kAdvanced));
  EXPECT_EQ("user", arl::toString(arl::ParameterTier::kUser));
  EXPECT_EQ("advanced", arl::toString(arl::ParameterTier::kAdvanced));
}

TEST(ParameterTiers, HelpListsTheUserTierAndSaysHowToListTheAdvancedOnes)
{
  const std::vector<arl::ParameterGroup> groups = { arl::ParameterGroup::kPreprocessor,
                                                    arl::ParameterGroup::kLocalizer };
  const std::string help = arl::parameterHelp(groups, false, "tool --help-advanced");
  const std::string all = arl::parameterHelp(groups, true, "tool --help-advanced");
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    if (spec.group != arl::ParameterGroup::kPreprocessor && spec.group != arl::ParameterGroup::kLocalizer)
      continue;
    const bool in_help = help.find("    " + spec.name + " = ") != std::string::npos;
    EXPECT_EQ(spec.tier == arl::ParameterTier::kUser, in_help) << spec.name;
    EXPECT_NE(std::string::npos, all.find("    " + spec.name + " = ")) << spec.name;
  }
  // 3 advanced rows of the preprocessor and 44 of the localizer (the test above names the others).
  EXPECT_NE(std::string::npos, help.find("  and 47 advanced parameters, not shown")) << help;
  EXPECT_NE(std::string::npos, help.find("tool --help-advanced lists them\n")) << help;
  EXPECT_EQ(std::string::npos, all.find("not shown")) << all;
  // With them: each group's advanced rows after its user rows, under their own heading.
  const size_t localizer = all.find("  localizer:\n"), advanced = all.find("  localizer, advanced:\n");
  ASSERT_NE(std::string::npos, localizer);
  ASSERT_NE(std::string::npos, advanced);
  EXPECT_LT(localizer, all.find("    end_of_route_keyframes = "));
  EXPECT_LT(all.find("    end_of_route_keyframes = "), advanced);
  EXPECT_LT(advanced, all.find("    stop_penalty = "));
  // A group without advanced rows has no such heading and no count.
  const std::string recorder = arl::parameterHelp({ arl::ParameterGroup::kMapRecorder }, false, "x");
  EXPECT_EQ(std::string::npos, recorder.find("advanced")) << recorder;
}

TEST_F(ParameterFile, ARemovedNameGetsAWarningWithTheValueItIsFixedAtAndTheOthersAreUsed)
{
  // contrast_min_std was a row of the table until it became kContrastMinStd (it only keeps eq. 2 from
  // dividing by zero). A params file written for the earlier version still names it.
  ASSERT_EQ(nullptr, arl::findParameter("contrast_min_std"));
  EXPECT_FLOAT_EQ(0.01f, arl::kContrastMinStd);
  const std::string sentence = arl::removedParameterSentence("contrast_min_std");
  EXPECT_EQ(0u, sentence.find("contrast_min_std was removed in this version; it is now fixed at 0.01 (")) << sentence;
  EXPECT_EQ(')', sentence.back()) << sentence;
  EXPECT_NE(std::string::npos, sentence.find("kContrastMinStd")) << sentence;
  EXPECT_EQ("", arl::removedParameterSentence("ring_buffer_rows"));
  EXPECT_EQ("", arl::removedParameterSentence("contrast_min_sd"));
  for (const arl::RemovedParameter& removed : arl::removedParameters())
    EXPECT_EQ(nullptr, arl::findParameter(removed.name)) << removed.name << " is removed and in the table";

  std::vector<std::string> warnings;
  ASSERT_TRUE(applyChecked("localizer:\n  ring_buffer_rows: 10\n  contrast_min_std: 0.05\n  max_step: 3\n",
                           &warnings));
  ASSERT_EQ(1u, warnings.size());
  EXPECT_EQ(path_ + ":3: " + sentence + "; the value given is ignored", warnings[0]);
  EXPECT_EQ(10, localizer_.ring_buffer_rows);
  EXPECT_EQ(3, localizer_.dtw.max_step);
  // One value at a time (--set, the nodelet): refused with the same sentence, nothing changed.
  arl::ParameterSet params;
  bool refused = false;
  EXPECT_EQ(sentence + "; the value given is ignored",
            arl::setParameterChecked("contrast_min_std", "0.05", &params, &refused));
  EXPECT_TRUE(refused);
  arl::PreprocessingParams preprocessing;
  arl::LocalizerParams localizer;
  std::string error;
  EXPECT_FALSE(arl::applyParameter("contrast_min_std", "0.05", &preprocessing, &localizer, &error));
  EXPECT_EQ(sentence, error);
  // The strict loader stops on it, naming the line and saying why.
  EXPECT_EQ(path_ + ":3: " + sentence,
            load("localizer:\n  ring_buffer_rows: 10\n  contrast_min_std: 0.05\n  max_step: 3\n"));
}

}  // namespace
