// The dynamic_reconfigure .cfg files agree with the core's parameter table (defaults, descriptions with
// the working range, no .cfg range), so a nodelet started without parameters behaves as localize_offline
// does with none; and what a config callback makes of a new config (corrections, changes).
#include <climits>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "glue/private_parameters.h"
#include "glue/reconfigure.h"

namespace arl = along_route_localization;

TEST(Reconfigure, PreprocessorCfgDefaultsAreTheCoreDefaults)
{
  const arl::PreprocessingParams core;
  const arl::PreprocessingParams from_cfg = arl::toParams(arl::PreprocessorConfig::__getDefault__());
  EXPECT_EQ(core.serialize(), from_cfg.serialize());
}

TEST(Reconfigure, LocalizerCfgDefaultsAreTheCoreDefaults)
{
  // Start from values no default has, so every field the .cfg maps is seen to come from the .cfg.
  arl::LocalizerParams base;
  base.method = arl::SequenceMethod::kSeqSlam;
  base.ring_buffer_rows = base.dtw.max_step = base.max_shift_px = base.contrast_window = base.search_radius =
      base.lost_after_frames = base.lost_window_frames = 999;
  base.confidence_threshold = base.horizontal_fov_rad = 0.999;
  base.dtw.stop_penalty = base.dtw.skip_penalty = base.motion_prior_weight = 999.0f;
  const arl::LocalizerParams cfg = arl::toParams(arl::LocalizerConfig::__getDefault__(), base);
  const arl::LocalizerParams core;
  EXPECT_EQ(arl::toString(core.method), arl::toString(cfg.method));
  EXPECT_EQ(core.ring_buffer_rows, cfg.ring_buffer_rows);
  EXPECT_EQ(core.dtw.max_step, cfg.dtw.max_step);
  EXPECT_EQ(core.max_shift_px, cfg.max_shift_px);
  EXPECT_EQ(core.contrast_window, cfg.contrast_window);
  EXPECT_EQ(core.search_radius, cfg.search_radius);
  EXPECT_EQ(core.lost_after_frames, cfg.lost_after_frames);
  EXPECT_EQ(core.lost_window_frames, cfg.lost_window_frames);
  EXPECT_DOUBLE_EQ(core.confidence_threshold, cfg.confidence_threshold);
  EXPECT_FLOAT_EQ(core.dtw.stop_penalty, cfg.dtw.stop_penalty);
  EXPECT_FLOAT_EQ(core.dtw.skip_penalty, cfg.dtw.skip_penalty);
  EXPECT_FLOAT_EQ(core.motion_prior_weight, cfg.motion_prior_weight);
  EXPECT_NEAR(core.horizontal_fov_rad, cfg.horizontal_fov_rad, 1e-6);
}

TEST(Reconfigure, RouteFollowerCfgDefaultsAreTheCoreDefaults)
{
  const arl::RouteFollowerParams core;
  const arl::RouteFollowerParams cfg = arl::toParams(arl::RouteFollowerConfig::__getDefault__());
  EXPECT_DOUBLE_EQ(core.homing_gain, cfg.homing_gain);
  EXPECT_DOUBLE_EQ(core.max_homing_turn_rps, cfg.max_homing_turn_rps);
  EXPECT_DOUBLE_EQ(core.homing_time_constant_s, cfg.homing_time_constant_s);
  EXPECT_DOUBLE_EQ(core.speed_factor, cfg.speed_factor);
  EXPECT_DOUBLE_EQ(core.min_confidence, cfg.min_confidence);
  EXPECT_EQ(core.slow_after_frames, cfg.slow_after_frames);
  EXPECT_EQ(core.stop_after_frames, cfg.stop_after_frames);
  EXPECT_DOUBLE_EQ(core.slow_factor, cfg.slow_factor);
  EXPECT_DOUBLE_EQ(core.recovery_distance_m, cfg.recovery_distance_m);
  EXPECT_DOUBLE_EQ(core.watchdog_timeout_s, cfg.watchdog_timeout_s);
  EXPECT_DOUBLE_EQ(core.max_linear_accel, cfg.max_linear_accel);
  EXPECT_DOUBLE_EQ(core.max_linear_decel, cfg.max_linear_decel);
  EXPECT_DOUBLE_EQ(core.max_angular_accel, cfg.max_angular_accel);
  // Each field from its own config field: values no default has come through.
  arl::RouteFollowerConfig config = arl::RouteFollowerConfig::__getDefault__();
  config.max_homing_turn_rate = 0.25;
  config.homing_time_constant = 0.75;
  config.watchdog_timeout = 2.5;
  config.recovery_distance = 7.5;
  config.max_linear_decel = 1.25;
  const arl::RouteFollowerParams changed = arl::toParams(config);
  EXPECT_DOUBLE_EQ(1.25, changed.max_linear_decel);
  EXPECT_DOUBLE_EQ(7.5, changed.recovery_distance_m);
  EXPECT_DOUBLE_EQ(0.25, changed.max_homing_turn_rps);
  EXPECT_DOUBLE_EQ(0.75, changed.homing_time_constant_s);
  EXPECT_DOUBLE_EQ(2.5, changed.watchdog_timeout_s);
}

TEST(Reconfigure, MapRecorderCfgDefaultsAreTheCoreDefaultsAndEachFieldComesFromTheCfg)
{
  const arl::KeyframePolicy core;
  arl::KeyframePolicy cfg = arl::toPolicy(arl::MapRecorderConfig::__getDefault__());
  EXPECT_EQ(core.every_nth, cfg.every_nth);
  EXPECT_DOUBLE_EQ(core.min_time_gap_s, cfg.min_time_gap_s);
  EXPECT_DOUBLE_EQ(core.min_appearance_change, cfg.min_appearance_change);
  EXPECT_DOUBLE_EQ(core.min_distance_m, cfg.min_distance_m);
  arl::MapRecorderConfig config = arl::MapRecorderConfig::__getDefault__();
  config.every_nth = 3;
  config.min_time_gap = 0.5;
  config.min_appearance_change = 7.0;
  config.min_distance = 2.5;
  cfg = arl::toPolicy(config);
  EXPECT_EQ(3, cfg.every_nth);
  EXPECT_DOUBLE_EQ(0.5, cfg.min_time_gap_s);
  EXPECT_DOUBLE_EQ(7.0, cfg.min_appearance_change);
  EXPECT_DOUBLE_EQ(2.5, cfg.min_distance_m);
}

TEST(Reconfigure, LocalizerFieldsTheCfgDoesNotHaveComeFromTheBase)
{
  arl::LocalizerParams base;
  base.min_texture_ratio = 0.77f;
  base.cost_function = arl::CostFunction::kCensus;
  base.dtw.exclusion_radius = 17;
  arl::LocalizerConfig config = arl::LocalizerConfig::__getDefault__();
  config.horizontal_fov_deg = 90.0;
  config.method = "no_such_method";
  const arl::LocalizerParams params = arl::toParams(config, base);
  EXPECT_FLOAT_EQ(0.77f, params.min_texture_ratio);
  EXPECT_EQ(arl::CostFunction::kCensus, params.cost_function);
  EXPECT_EQ(17, params.dtw.exclusion_radius);
  EXPECT_NEAR(M_PI / 2, params.horizontal_fov_rad, 1e-12);
  EXPECT_EQ(arl::SequenceMethod::kOnlineDtw, params.method);
}

TEST(Reconfigure, AnUnknownEnumNameIsNamedSoTheNodeletCanRejectIt)
{
  // dynparam and rqt_reconfigure send any string for an enum parameter; a misspelt one must not pass
  // for another setting without a word.
  arl::LocalizerConfig localizer = arl::LocalizerConfig::__getDefault__();
  std::string problem;
  arl::toParams(localizer, arl::LocalizerParams(), &problem);
  EXPECT_EQ("", problem);
  localizer.method = "seqslm";
  arl::toParams(localizer, arl::LocalizerParams(), &problem);
  EXPECT_EQ("method 'seqslm' is not one of dtw | seqslam", problem);

  arl::PreprocessorConfig preprocessor = arl::PreprocessorConfig::__getDefault__();
  problem.clear();
  arl::toParams(preprocessor, &problem);
  EXPECT_EQ("", problem);
  preprocessor.normalization = "divisve";
  arl::toParams(preprocessor, &problem);
  EXPECT_EQ("normalization 'divisve' is not one of patch | divisive | none", problem);
}

namespace
{

/// Every parameter of Config (a .cfg) against the table: a row of `group`, the description "doc [range]",
/// the table's default, no range of its own (dynamic_reconfigure would clamp without a word), and for a
/// choice the same names. Each row of `group` is in the .cfg when `all_rows`.
template <class Config>
void expectCfgAgreesWithTheTable(arl::ParameterGroup group, bool all_rows)
{
  const dynamic_reconfigure::ConfigDescription description = Config::__getDescriptionMessage__();
  std::set<std::string> in_cfg;
  for (const auto& cfg_group : description.groups)
  {
    // The tiers (ParameterTier): the user tier at the top level ("Default"), the advanced one in the group
    // "advanced", which rqt_reconfigure shows collapsed; no other group.
    ASSERT_TRUE(cfg_group.name == "Default" || cfg_group.name == "advanced") << cfg_group.name;
    const arl::ParameterTier tier =
        cfg_group.name == "Default" ? arl::ParameterTier::kUser : arl::ParameterTier::kAdvanced;
    if (tier == arl::ParameterTier::kAdvanced)
    {
      EXPECT_EQ("collapse", cfg_group.type);
      EXPECT_FALSE(cfg_group.parameters.empty());
    }
    for (const dynamic_reconfigure::ParamDescription& param : cfg_group.parameters)
    {
      SCOPED_TRACE(param.name);
      in_cfg.insert(param.name);
      const arl::ParameterSpec* spec = arl::findParameter(param.name);
      ASSERT_NE(nullptr, spec) << "not in the parameter table";
      EXPECT_EQ(arl::toString(group), arl::toString(spec->group));
      EXPECT_EQ(arl::toString(spec->tier), arl::toString(tier)) << "the .cfg puts it in group " << cfg_group.name;
      EXPECT_EQ(spec->doc + " [" + spec->rangeText() + "]", param.description);
      const arl::ParameterSet defaults;
      if (spec->type == arl::ParameterType::kChoice)
      {
        ASSERT_EQ("str", param.type);
        EXPECT_EQ(spec->defaultText(), arl::findByName(description.dflt.strs, param.name)->value);
        size_t listed = 0;
        for (size_t at = param.edit_method.find("'value'"); at != std::string::npos;
             at = param.edit_method.find("'value'", at + 1))
          ++listed;
        EXPECT_EQ(spec->choices.size(), listed) << param.edit_method;
        for (const std::string& choice : spec->choices)
          EXPECT_NE(std::string::npos, param.edit_method.find("'value': '" + choice + "'")) << param.edit_method;
      }
      else if (spec->type == arl::ParameterType::kInt)
      {
        ASSERT_EQ("int", param.type);
        EXPECT_EQ(spec->get_number(defaults), arl::findByName(description.dflt.ints, param.name)->value);
        EXPECT_EQ(INT_MIN, arl::findByName(description.min.ints, param.name)->value) << "a .cfg range: clamped silently";
        EXPECT_EQ(INT_MAX, arl::findByName(description.max.ints, param.name)->value) << "a .cfg range: clamped silently";
      }
      else if (spec->type == arl::ParameterType::kDouble)
      {
        ASSERT_EQ("double", param.type);
        const double table = spec->get_number(defaults);
        EXPECT_NEAR(table, arl::findByName(description.dflt.doubles, param.name)->value, 1e-6 * std::max(1.0, std::abs(table)));
        EXPECT_EQ(-std::numeric_limits<double>::infinity(), arl::findByName(description.min.doubles, param.name)->value);
        EXPECT_EQ(std::numeric_limits<double>::infinity(), arl::findByName(description.max.doubles, param.name)->value);
      }
      else
      {
        ASSERT_EQ("bool", param.type);
      }
    }
  }
  if (!all_rows)
    return;
  for (const arl::ParameterSpec& spec : arl::parameterTable())
  {
    if (spec.group == group)
    {
      EXPECT_TRUE(in_cfg.count(spec.name)) << spec.name << " is missing from the .cfg";
    }
  }
}

}  // namespace

TEST(Reconfigure, TheCfgFilesAgreeWithTheParameterTable)
{
  expectCfgAgreesWithTheTable<arl::PreprocessorConfig>(arl::ParameterGroup::kPreprocessor, true);
  expectCfgAgreesWithTheTable<arl::LocalizerConfig>(arl::ParameterGroup::kLocalizer, false);
  expectCfgAgreesWithTheTable<arl::MapRecorderConfig>(arl::ParameterGroup::kMapRecorder, true);
  expectCfgAgreesWithTheTable<arl::RouteFollowerConfig>(arl::ParameterGroup::kRouteFollower, true);
}

TEST(Reconfigure, AParameterOfTheCollapsedGroupIsSetByItsNameAsBefore)
{
  // What dynparam set /localizer stop_penalty 0.5 and rqt_reconfigure send: a Config message naming the
  // values changed, flat, whatever group the .cfg puts them in.
  dynamic_reconfigure::Config message;
  dynamic_reconfigure::DoubleParameter stop_penalty;
  stop_penalty.name = "stop_penalty";
  stop_penalty.value = 0.5;
  message.doubles.push_back(stop_penalty);
  dynamic_reconfigure::IntParameter lost_after_frames;
  lost_after_frames.name = "lost_after_frames";
  lost_after_frames.value = 4;
  message.ints.push_back(lost_after_frames);
  arl::LocalizerConfig config = arl::LocalizerConfig::__getDefault__();
  ASSERT_TRUE(config.__fromMessage__(message));
  EXPECT_DOUBLE_EQ(0.5, config.stop_penalty);
  EXPECT_EQ(4, config.lost_after_frames);
  const arl::LocalizerParams params = arl::toParams(config, arl::LocalizerParams());
  EXPECT_FLOAT_EQ(0.5f, params.dtw.stop_penalty);
  EXPECT_EQ(4, params.lost_after_frames);
  // And what dynparam get lists: every parameter by its name, the user tier's and the advanced group's.
  dynamic_reconfigure::Config all;
  config.__toMessage__(all);
  std::set<std::string> listed;
  for (const auto& d : all.doubles)
    listed.insert(d.name);
  for (const auto& i : all.ints)
    listed.insert(i.name);
  for (const auto& s : all.strs)
    listed.insert(s.name);
  for (const auto& b : all.bools)
    listed.insert(b.name);
  EXPECT_EQ(arl::configParameterNames<arl::LocalizerConfig>(), listed);
  EXPECT_EQ(13u, listed.size());  // 8 of the user tier, 5 advanced (Localizer.cfg)
  EXPECT_TRUE(listed.count("stop_penalty") && listed.count("ring_buffer_rows"));
  // The group starts collapsed: the initial state the server gives it (__fromServer__, setInitialState) is
  // false, which rqt_reconfigure shows as a closed group.
  bool advanced_listed = false;
  for (const auto& group : arl::LocalizerConfig::__getGroupDescriptions__())
    if (group->name == "advanced")
    {
      advanced_listed = true;
      EXPECT_FALSE(group->state);
      EXPECT_EQ("collapse", group->type);
    }
  EXPECT_TRUE(advanced_listed);
}

TEST(Reconfigure, ARemovedPrivateParameterIsNamedAsRemovedWithItsFixedValue)
{
  // ~contrast_min_std in a launch file of the earlier version: not "misspelt?", but what became of it.
  const std::string sentence = arl::unreadSentence("contrast_min_std", "localizer", { "ring_buffer_rows" });
  EXPECT_EQ("~" + arl::removedParameterSentence("contrast_min_std") + "; the value given is ignored", sentence);
  EXPECT_EQ(0u, sentence.find("~contrast_min_std was removed in this version; it is now fixed at 0.01")) << sentence;
  EXPECT_EQ(0u, arl::unreadSentence("ring_bufer_rows", "localizer", { "ring_buffer_rows" })
                    .find("~ring_bufer_rows is not a parameter of the localizer and is ignored (did you mean "
                          "ring_buffer_rows?)"));
}

TEST(Reconfigure, ValuesOutsideTheWorkingRangeAreCorrectedAndBadChoicesKeepThePreviousValue)
{
  arl::LocalizerConfig previous = arl::LocalizerConfig::__getDefault__();
  arl::LocalizerConfig config = previous;
  config.ring_buffer_rows = -3;  // dynparam set /localizer ring_buffer_rows -3
  config.method = "DTW";
  config.max_step = 3;
  config.confidence_threshold = 1.5;
  const std::vector<std::string> corrections = arl::correctToTable(config, previous);
  ASSERT_EQ(3u, corrections.size());
  EXPECT_EQ("ring_buffer_rows -3 is outside 3 .. 1000 frames; using 3", corrections[0]);
  EXPECT_EQ("confidence_threshold 1.5 is outside 0 .. 1; using 1", corrections[1]);
  EXPECT_EQ("method 'DTW' is not one of dtw | seqslam; keeping dtw", corrections[2]);
  EXPECT_EQ(3, config.ring_buffer_rows);
  EXPECT_EQ("dtw", config.method);
  EXPECT_EQ(3, config.max_step);  // the good value is kept
  EXPECT_DOUBLE_EQ(1.0, config.confidence_threshold);

  arl::MapRecorderConfig recorder = arl::MapRecorderConfig::__getDefault__();
  recorder.every_nth = 0;
  recorder.min_distance = -1.0;
  const std::vector<std::string> recorder_corrections =
      arl::correctToTable(recorder, arl::MapRecorderConfig::__getDefault__());
  ASSERT_EQ(2u, recorder_corrections.size());
  EXPECT_EQ("every_nth 0 is outside 1 .. 1000 frames; using 1", recorder_corrections[0]);
  EXPECT_EQ("min_distance -1 is outside 0 .. 10000 m; using 0", recorder_corrections[1]);

  // The route follower's, by the table's ranges (its .cfg declares none either).
  arl::RouteFollowerConfig follower = arl::RouteFollowerConfig::__getDefault__();
  follower.homing_gain = 25.0;
  follower.watchdog_timeout = 0.0;
  follower.slow_after_frames = 4;
  const std::vector<std::string> follower_corrections =
      arl::correctToTable(follower, arl::RouteFollowerConfig::__getDefault__());
  ASSERT_EQ(2u, follower_corrections.size());
  EXPECT_EQ("homing_gain 25 is outside 0 .. 20 rad/s per rad; using 20", follower_corrections[0]);
  EXPECT_EQ("watchdog_timeout 0 is outside 0.01 .. 60 s; using 0.01", follower_corrections[1]);
  EXPECT_DOUBLE_EQ(20.0, follower.homing_gain);
  EXPECT_DOUBLE_EQ(0.01, follower.watchdog_timeout);
  EXPECT_EQ(4, follower.slow_after_frames);
  EXPECT_EQ("", arl::toParams(follower).validate());
}

TEST(Reconfigure, AReviewListsEachChangeOnceOrRestoresTheLastValidConfig)
{
  arl::LocalizerConfig last_valid = arl::LocalizerConfig::__getDefault__();
  arl::LocalizerConfig config = last_valid;
  config.ring_buffer_rows = 10;
  config.skip_penalty = 0.5;
  arl::ConfigReview review = arl::reviewConfig(config, last_valid, { "a correction" }, "");
  EXPECT_EQ(std::vector<std::string>{ "a correction" }, review.corrections);
  EXPECT_EQ((std::vector<std::string>{ "ring_buffer_rows 30 -> 10", "skip_penalty 0.85 -> 0.5" }), review.changes);
  EXPECT_EQ("", review.rejected);
  EXPECT_EQ(10, last_valid.ring_buffer_rows);
  // The same config again: nothing changed, nothing said.
  review = arl::reviewConfig(config, last_valid, {}, "");
  EXPECT_TRUE(review.changes.empty());
  // A combination validate() refuses: the last valid config comes back, and no change is claimed.
  config.ring_buffer_rows = 20;
  review = arl::reviewConfig(config, last_valid, {}, "some reason");
  EXPECT_EQ("some reason", review.rejected);
  EXPECT_TRUE(review.changes.empty());
  EXPECT_EQ(10, config.ring_buffer_rows);
}
