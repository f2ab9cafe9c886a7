// The dynamic_reconfigure defaults (cfg/*.cfg) are the core defaults, so a nodelet started without
// parameters behaves as localize_offline does with none.
#include <cmath>

#include <gtest/gtest.h>

#include "ros/reconfigure.h"

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
  EXPECT_DOUBLE_EQ(core.watchdog_timeout_s, cfg.watchdog_timeout_s);
  EXPECT_DOUBLE_EQ(core.max_linear_accel, cfg.max_linear_accel);
  EXPECT_DOUBLE_EQ(core.max_angular_accel, cfg.max_angular_accel);
  // Each field from its own config field: values no default has come through.
  arl::RouteFollowerConfig config = arl::RouteFollowerConfig::__getDefault__();
  config.max_homing_turn_rate = 0.25;
  config.homing_time_constant = 0.75;
  config.watchdog_timeout = 2.5;
  const arl::RouteFollowerParams changed = arl::toParams(config);
  EXPECT_DOUBLE_EQ(0.25, changed.max_homing_turn_rps);
  EXPECT_DOUBLE_EQ(0.75, changed.homing_time_constant_s);
  EXPECT_DOUBLE_EQ(2.5, changed.watchdog_timeout_s);
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
  EXPECT_EQ("method must be 'dtw' or 'seqslam', got 'seqslm'", problem);

  arl::PreprocessorConfig preprocessor = arl::PreprocessorConfig::__getDefault__();
  problem.clear();
  arl::toParams(preprocessor, &problem);
  EXPECT_EQ("", problem);
  preprocessor.normalization = "divisve";
  arl::toParams(preprocessor, &problem);
  EXPECT_EQ("normalization must be 'divisive', 'patch' or 'none', got 'divisve'", problem);
}
