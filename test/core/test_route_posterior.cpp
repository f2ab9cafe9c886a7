// Step 5's posterior (route_posterior.h): the motion model, the evidence and the window, on hand-worked numbers.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/route_posterior.h"

namespace arl = along_route_localization;

namespace
{

arl::PosteriorParams exactParams(int max_step = 2)
{
  arl::PosteriorParams params;
  params.speed_change = 0.0;
  params.jump = 0.0;
  params.start_doubt = 0.0;
  params.max_step = max_step;
  return params;
}

double totalMass(const arl::RoutePosterior& posterior)
{
  double total = 0.0;
  for (int k = 0; k < posterior.keyframes(); ++k)
    total += posterior.keyframeMass(k);
  return total;
}

}  // namespace

// From a known start at keyframe 0, speeds 0, 1/2, 1, 3/2, 2 keyframes per frame equally likely: after one
// frame the positions 0, 1/2, 1, 3/2, 2 hold 0.2 each; a keyframe takes its position and half of each
// neighbouring midpoint (0.2 + 0.1 = 0.3 at keyframe 0, 0.2 + 0.1 + 0.1 = 0.4 at 1). After two frames the
// keyframes 0..4 hold 0.2 each.
TEST(RoutePosterior, WithoutEvidenceTheBeliefMovesOnAtEverySpeed)
{
  arl::RoutePosterior posterior(exactParams());
  posterior.reset(10, 0);
  EXPECT_DOUBLE_EQ(1.0, posterior.keyframeMass(0));
  posterior.predict();
  EXPECT_NEAR(0.3, posterior.keyframeMass(0), 1e-12);
  EXPECT_NEAR(0.4, posterior.keyframeMass(1), 1e-12);
  EXPECT_NEAR(0.3, posterior.keyframeMass(2), 1e-12);
  EXPECT_NEAR(0.0, posterior.keyframeMass(3), 1e-12);
  EXPECT_NEAR(1.0, posterior.withinOne(1), 1e-12);
  EXPECT_NEAR(0.7, posterior.withinOne(0), 1e-12);
  EXPECT_NEAR(0.3, posterior.withinOne(3), 1e-12);
  posterior.predict();
  for (int k = 0; k < 5; ++k)
    EXPECT_NEAR(0.2, posterior.keyframeMass(k), 1e-12) << k;
  EXPECT_NEAR(0.6, posterior.withinOne(2), 1e-12);
  EXPECT_NEAR(0.4, posterior.withinOne(0), 1e-12);
  EXPECT_NEAR(0.2, posterior.withinOne(5), 1e-12);
  EXPECT_NEAR(0.0, posterior.withinOne(6), 1e-12);
}

// At the route's end the robot stays at the last keyframe: from keyframe 1 of 3, the speeds 1 to 2 end at or
// past it (positions 2, 5/2 and 3 of a route ending at 2), so the last keyframe holds 0.6 + half of 0.2
// (position 3/2).
TEST(RoutePosterior, TheRouteEndHoldsARobotThatDrivesOn)
{
  arl::RoutePosterior posterior(exactParams());
  posterior.reset(3, 1);
  posterior.predict();
  EXPECT_NEAR(0.0, posterior.keyframeMass(0), 1e-12);
  EXPECT_NEAR(0.3, posterior.keyframeMass(1), 1e-12);
  EXPECT_NEAR(0.7, posterior.keyframeMass(2), 1e-12);
  posterior.predict(20);  // every moving speed ends at the last keyframe; speed 0 (no speed change) stands
  EXPECT_NEAR(0.8, posterior.keyframeMass(2), 1e-12);
  EXPECT_NEAR(0.2, posterior.keyframeMass(1), 1e-12);
}

// A known start doubted by half: half the belief spread evenly over the 9 positions of 5 keyframes, half at
// keyframe 2. Keyframe 2: 0.5 + 1/18 + 2 * 1/36 = 0.5 + 1/9; keyframes 1 and 3: 1/9 each.
TEST(RoutePosterior, AKnownStartKeepsItsDoubtSpreadOverTheRoute)
{
  arl::PosteriorParams params = exactParams();
  params.start_doubt = 0.5;
  arl::RoutePosterior posterior(params);
  posterior.reset(5, 2);
  EXPECT_NEAR(0.5 + 1.0 / 9.0, posterior.keyframeMass(2), 1e-12);
  EXPECT_NEAR(1.0 / 9.0, posterior.keyframeMass(1), 1e-12);
  EXPECT_NEAR(0.5 + 3.0 / 9.0, posterior.withinOne(2), 1e-12);
  EXPECT_NEAR(1.0, totalMass(posterior), 1e-12);
}

// With probability jump the robot is anywhere: from keyframe 0 at speeds 0, 1/2, 1 (max_step 1), the 19
// positions of 10 keyframes each get 0.1 / 19, the rest moves as before, 0.9 / 3 to each of positions 0..2.
TEST(RoutePosterior, AJumpSpreadsItsShareOverTheRoute)
{
  arl::PosteriorParams params = exactParams(1);
  params.jump = 0.1;
  arl::RoutePosterior posterior(params);
  posterior.reset(10, 0);
  posterior.predict();
  const double spread = 0.1 / 19.0;
  EXPECT_NEAR(1.5 * spread, posterior.keyframeMass(9), 1e-12);
  EXPECT_NEAR(2.0 * spread, posterior.keyframeMass(5), 1e-12);
  EXPECT_NEAR(0.3 + 0.15 + 1.5 * spread, posterior.keyframeMass(0), 1e-12);
  EXPECT_NEAR(1.0, totalMass(posterior), 1e-12);
}

// Route of 4 keyframes, belief even over its 7 positions; costs 0, a, a, a with exp(-a / cost_scale) = 1/4:
// position weights 1, 1/2 (the midpoint: the geometric mean), then 1/4 for the other five; their sum 11/4.
// Keyframe 0: (1 + 1/4 * 1/2) / (11/4) = 5/11; 1: (1/4 + 1/2 * (1/2 + 1/4)) / (11/4) = 2.5/11; 2: 2/11;
// 3: 1.5/11.
TEST(RoutePosterior, EvidenceWeighsKeyframesAndTheMidpointsBetweenThem)
{
  arl::PosteriorParams params = exactParams();
  params.cost_scale = 0.05;
  arl::RoutePosterior posterior(params);
  posterior.reset(4, -1);
  const float a = static_cast<float>(0.05 * std::log(4.0));
  const std::vector<float> costs = { 0.0f, a, a, a };
  posterior.observe(costs.data(), nullptr, 0, 4);
  EXPECT_NEAR(5.0 / 11.0, posterior.keyframeMass(0), 1e-6);
  EXPECT_NEAR(2.5 / 11.0, posterior.keyframeMass(1), 1e-6);
  EXPECT_NEAR(2.0 / 11.0, posterior.keyframeMass(2), 1e-6);
  EXPECT_NEAR(1.5 / 11.0, posterior.keyframeMass(3), 1e-6);
  EXPECT_NEAR(3.5 / 11.0, posterior.withinOne(3), 1e-6);
  EXPECT_NEAR(9.5 / 11.0, posterior.withinOne(1), 1e-6);
  EXPECT_EQ(0, posterior.mostLikely());
}

// A featureless keyframe (usable 0) matches a dark query by chance: its cost is no evidence. The usable ones
// cost the same, so nothing changes: keyframes 1.5/7, 2/7, 2/7, 1.5/7. Taken as usable, keyframe 2 draws
// the belief.
TEST(RoutePosterior, AFeaturelessKeyframeIsNoEvidence)
{
  arl::PosteriorParams params = exactParams();
  params.cost_scale = 0.05;
  const std::vector<float> costs = { 0.5f, 0.5f, 0.0f, 0.5f };
  const std::vector<uint8_t> usable = { 1, 1, 0, 1 };
  arl::RoutePosterior posterior(params);
  posterior.reset(4, -1);
  posterior.observe(costs.data(), usable.data(), 0, 4);
  EXPECT_NEAR(2.0 / 7.0, posterior.keyframeMass(2), 1e-12);
  EXPECT_NEAR(1.5 / 7.0, posterior.keyframeMass(3), 1e-12);
  const std::vector<uint8_t> none = { 0, 0, 0, 0 };
  posterior.observe(costs.data(), none.data(), 0, 4);  // no usable keyframe: no evidence
  EXPECT_NEAR(2.0 / 7.0, posterior.keyframeMass(2), 1e-12);
  posterior.observe(costs.data(), nullptr, 0, 4);
  EXPECT_GT(posterior.keyframeMass(2), 0.99);
}

// A frame compared with keyframes 40-59 of 100 (a tracking band): the window becomes those keyframes, and the
// rest of the route keeps its mass as an even spread weighed by the median likelihood. Belief even over the
// 199 positions; keyframe 50 costs least, the others ln(100) * cost_scale more: weights 1 at position 100,
// 1/10 at the midpoints 99 and 101, 1/100 at the 36 other positions of the window and at the 160 outside it.
// Sum (1 + 0.2 + 0.36 + 1.6) / 199 = 3.16 / 199.
TEST(RoutePosterior, OutsideItsWindowTheBeliefIsAnEvenSpread)
{
  arl::PosteriorParams params = exactParams();
  params.cost_scale = 0.02;
  arl::RoutePosterior posterior(params);
  posterior.reset(100, -1);
  std::vector<float> costs(20, static_cast<float>(0.02 * std::log(100.0)));
  costs[10] = 0.0f;  // keyframe 50
  posterior.observe(costs.data(), nullptr, 40, 20);
  EXPECT_EQ(40, posterior.windowFirst());
  EXPECT_EQ(20, posterior.windowWidth());
  EXPECT_NEAR(1.1 / 3.16, posterior.keyframeMass(50), 1e-6);
  EXPECT_NEAR(0.065 / 3.16, posterior.keyframeMass(49), 1e-6);
  EXPECT_NEAR(1.23 / 3.16, posterior.withinOne(50), 1e-6);
  EXPECT_NEAR(0.02 / 3.16, posterior.keyframeMass(10), 1e-6);  // outside: 1/100 per position
  EXPECT_NEAR(0.02 / 3.16, posterior.keyframeMass(40), 1e-6);  // the window's edge, half of a midpoint outside
  EXPECT_NEAR(1.0, totalMass(posterior), 1e-9);
  EXPECT_EQ(50, posterior.mostLikely());
}

// The window follows the band: what leaves it joins the even spread, what enters takes the spread's share,
// and the belief still sums to 1 with every part of the motion model on.
TEST(RoutePosterior, AMovingWindowKeepsTheWholeBelief)
{
  arl::PosteriorParams params;
  params.cost_scale = 0.03;
  params.speed_change = 0.05;
  params.jump = 0.01;
  params.start_doubt = 0.5;
  arl::RoutePosterior posterior(params);
  posterior.reset(200, 10);
  for (int frame = 0; frame < 60; ++frame)
  {
    posterior.predict();
    const int first = std::max(0, 10 + frame - 20);
    std::vector<float> costs(41, 0.6f);
    const int place = 10 + frame;  // the robot drives one keyframe per frame
    costs[place - first] = 0.3f;
    posterior.observe(costs.data(), nullptr, first, 41);
    ASSERT_NEAR(1.0, totalMass(posterior), 1e-9) << "frame " << frame;
  }
  EXPECT_EQ(69, posterior.mostLikely());
  EXPECT_GT(posterior.withinOne(69), 0.95);
  EXPECT_LT(posterior.withinOne(150), 0.01);
}

TEST(RoutePosterior, RefusesParametersOutOfTheirRange)
{
  arl::PosteriorParams params;
  params.cost_scale = 0.0;
  EXPECT_THROW(arl::RoutePosterior{ params }, std::invalid_argument);
  params = arl::PosteriorParams();
  params.jump = 1.5;
  EXPECT_NE(std::string::npos, params.validate().find("posterior_jump"));
  params = arl::PosteriorParams();
  params.start_doubt = -0.1;
  EXPECT_NE(std::string::npos, params.validate().find("posterior_start_doubt"));
  params = arl::PosteriorParams();
  params.speed_change = std::nan("");
  EXPECT_NE(std::string::npos, params.validate().find("posterior_speed_change"));
  arl::RoutePosterior posterior;
  EXPECT_THROW(posterior.reset(0, -1), std::invalid_argument);
}

// A new fastest speed is another set of speeds: each position keeps its mass, spread over the new speeds.
TEST(RoutePosterior, ANewMaxStepKeepsWhereTheRobotMayBe)
{
  arl::RoutePosterior posterior(exactParams(2));
  posterior.reset(10, 3);
  posterior.predict(2);
  std::vector<double> before;
  for (int k = 0; k < 10; ++k)
    before.push_back(posterior.keyframeMass(k));
  EXPECT_NEAR(0.2, before[5], 1e-12);  // keyframes 3..7 hold 0.2 each
  posterior.setParams(exactParams(1));
  for (int k = 0; k < 10; ++k)
    EXPECT_NEAR(before[k], posterior.keyframeMass(k), 1e-12) << k;
  posterior.predict();  // speeds 0, 1/2, 1 now: from keyframe 3's 0.2, a third stays there
  EXPECT_NEAR(0.2 / 3.0 + 0.5 * 0.2 / 3.0, posterior.keyframeMass(3), 1e-12);
}

// With the belief spread evenly, the even spread outside the window is exact: one frame of the motion model on
// a window gives, inside it, what the whole route's filter gives (the mass that enters the window's start
// from outside, at every speed, and the jump). Before, the mass entering at speed v landed in the window's
// first v positions whatever the window's distance from the route's start.
TEST(RoutePosterior, OnAWindowTheMotionModelIsTheWholeRoutes)
{
  arl::PosteriorParams params;
  params.speed_change = 0.1;
  params.jump = 0.05;
  for (const int max_step : { 1, 2, 3 })
  {
    params.max_step = max_step;
    for (const int first : { 1, 2, 5 })
    {
      arl::RoutePosterior whole(params), window(params);
      whole.reset(12, -1);
      window.reset(12, -1);
      window.moveTo(first, 3);
      whole.predict();
      window.predict();
      // The middle keyframe: its position and both midpoints are inside the window (an edge keyframe's outer
      // midpoint is read from the even spread).
      EXPECT_NEAR(whole.keyframeMass(first + 1), window.keyframeMass(first + 1), 1e-12)
          << "max_step " << max_step << ", window from " << first;
      EXPECT_NEAR(1.0, totalMass(window), 1e-12);
    }
  }
}

// Frames without evidence (dark, featureless) while the band moves on: the window follows the band, so the
// belief moving along with the robot stays in it; left behind, it would run out of the window into the even
// spread and the answer's confidence fall to nothing (0.003 after 50 frames, measured before the window
// followed the band).
TEST(RoutePosterior, TheWindowFollowsTheBandThroughFramesWithoutEvidence)
{
  arl::PosteriorParams params;  // the defaults
  arl::RoutePosterior posterior(params);
  posterior.reset(1000, 0);
  int place = 0;
  for (; place < 100; ++place)  // tracked at one keyframe per frame
  {
    const int first = std::max(0, place - 40);
    posterior.moveTo(first, 81);
    posterior.predict();
    std::vector<float> costs(81, 0.6f);
    costs[place - first] = 0.3f;
    posterior.observe(costs.data(), nullptr, first, 81);
  }
  EXPECT_GT(posterior.withinOne(place - 1), 0.99);
  for (int frame = 0; frame < 50; ++frame, ++place)  // 50 frames without evidence, the band moving on
  {
    posterior.moveTo(place - 40, 81);
    posterior.predict();
  }
  EXPECT_EQ(place - 41, posterior.windowFirst());  // the band of the last frame, at place - 1
  EXPECT_GT(posterior.withinOne(place - 1), 0.1);  // the belief spreads around the reckoned place
  EXPECT_LT(posterior.withinOne(place - 1), 0.5);
  EXPECT_NEAR(1.0, totalMass(posterior), 1e-9);
}

// A row that lies off the route (an API misuse the Localizer never makes) is no evidence, and only the
// entries on the route count.
TEST(RoutePosterior, EntriesOffTheRouteAreIgnored)
{
  arl::PosteriorParams params = exactParams();
  params.cost_scale = 0.05;
  arl::RoutePosterior posterior(params);
  posterior.reset(10, -1);
  const std::vector<float> costs = { 0.0f, 0.5f, 0.5f, 0.5f, 0.5f };
  posterior.observe(costs.data(), nullptr, 12, 3);   // keyframes 12..14: none on the route
  posterior.observe(costs.data(), nullptr, -8, 3);   // keyframes -8..-6: none either
  EXPECT_NEAR(2.0 / 19.0, posterior.keyframeMass(5), 1e-12);
  EXPECT_EQ(0, posterior.windowFirst());
  EXPECT_EQ(10, posterior.windowWidth());
  posterior.observe(costs.data(), nullptr, -1, 5);   // keyframes 0..3 from entries 1..4: all equal, no evidence
  EXPECT_NEAR(2.0 / 19.0, posterior.keyframeMass(5), 1e-12);  // the cost 0 at keyframe -1 did not count
  EXPECT_EQ(0, posterior.windowFirst());
  EXPECT_EQ(4, posterior.windowWidth());
}
