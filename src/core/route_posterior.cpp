#include "along_route_localization/route_posterior.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace along_route_localization
{

std::string PosteriorParams::validate() const
{
  if (!(cost_scale > 0.0) || !std::isfinite(cost_scale))
    return "posterior_cost_scale must be > 0";
  if (!(speed_change >= 0.0 && speed_change <= 1.0))
    return "posterior_speed_change must be in [0, 1]";
  if (!(jump >= 0.0 && jump <= 1.0))
    return "posterior_jump must be in [0, 1]";
  if (!(start_doubt >= 0.0 && start_doubt <= 1.0))
    return "posterior_start_doubt must be in [0, 1]";
  if (max_step < 1 || max_step > 16)
    return "max_step must be in [1, 16]";
  return "";
}

RoutePosterior::RoutePosterior(const PosteriorParams& params)
{
  setParams(params);
}

void RoutePosterior::setParams(const PosteriorParams& params)
{
  const std::string invalid = params.validate();
  if (!invalid.empty())
    throw std::invalid_argument("RoutePosterior: " + invalid);
  const int old_speeds = speeds();
  params_ = params;
  if (speeds() == old_speeds || keyframes_ < 1)
    return;
  // Another set of speeds: each position keeps its mass, spread evenly over the new speeds.
  const int x_count = positions(), v_count = speeds();
  next_.assign(static_cast<size_t>(v_count) * x_count, 0.0);
  for (int x = 0; x < x_count; ++x)
  {
    double mass = 0.0;
    for (int v = 0; v < old_speeds; ++v)
      mass += p_[static_cast<size_t>(v) * x_count + x];
    for (int v = 0; v < v_count; ++v)
      next_[static_cast<size_t>(v) * x_count + x] = mass / v_count;
  }
  p_.swap(next_);
}

void RoutePosterior::reset(int keyframes, int start)
{
  if (keyframes < 1)
    throw std::invalid_argument("RoutePosterior: a route has at least one keyframe");
  keyframes_ = keyframes;
  start_ = start < 0 ? -1 : std::min(start, keyframes - 1);
  lo_ = 0;
  hi_ = keyframes;
  elsewhere_ = 0.0;
  const int v_count = speeds(), x_count = positions();
  const double spread = start_ < 0 ? 1.0 : params_.start_doubt;
  p_.assign(static_cast<size_t>(v_count) * x_count, spread / (static_cast<double>(v_count) * x_count));
  if (start_ >= 0)
    for (int v = 0; v < v_count; ++v)
      p_[static_cast<size_t>(v) * x_count + 2 * start_] += (1.0 - params_.start_doubt) / v_count;
}

double RoutePosterior::outsideDensity() const
{
  const int outside = allPositions() - positions();
  return outside > 0 ? std::max(0.0, elsewhere_) / outside : 0.0;
}

void RoutePosterior::predict(int frames)
{
  if (keyframes_ < 1)
    return;
  const int v_count = speeds(), x_count = positions();
  const double q = params_.speed_change, eps = params_.jump;
  next_.resize(p_.size());
  for (int f = 0; f < frames; ++f)
  {
    // The speed changes by half a keyframe per frame, up or down; at the slowest and fastest speeds the
    // change that would leave the range keeps the speed.
    for (int v = 0; v < v_count; ++v)
    {
      const double* own = &p_[static_cast<size_t>(v) * x_count];
      const double* down = &p_[static_cast<size_t>(v > 0 ? v - 1 : v) * x_count];
      const double* up = &p_[static_cast<size_t>(v + 1 < v_count ? v + 1 : v) * x_count];
      double* out = &next_[static_cast<size_t>(v) * x_count];
      for (int x = 0; x < x_count; ++x)
        out[x] = (1.0 - q) * own[x] + 0.5 * q * (down[x] + up[x]);
    }
    // The position moves on by the speed (v half keyframes). Past the window's end: elsewhere, or at the
    // route's end, the last keyframe. Into the window's start: from the even spread outside it.
    const double density = outsideDensity() / v_count;  // one position and speed outside the window
    double inflow = 0.0;
    std::fill(p_.begin(), p_.end(), 0.0);
    for (int v = 0; v < v_count; ++v)
    {
      const double* in = &next_[static_cast<size_t>(v) * x_count];
      double* out = &p_[static_cast<size_t>(v) * x_count];
      for (int x = 0; x < x_count; ++x)
      {
        const int to = x + v;
        if (to < x_count)
          out[to] += in[x];
        else if (hi_ == keyframes_)
          out[x_count - 1] += in[x];
        else
          elsewhere_ += in[x];
      }
      // From the positions left of the window (route positions [0, 2 lo_)), v positions on: into the
      // window, or past it (at the route's end: its last keyframe; else it stays elsewhere).
      for (int source = std::max(0, 2 * lo_ - v); source < 2 * lo_; ++source)
      {
        const int to = source + v - 2 * lo_;
        if (to < x_count)
          out[to] += density;
        else if (hi_ == keyframes_)
          out[x_count - 1] += density;
        else
          continue;
        inflow += density;
      }
    }
    elsewhere_ = std::max(0.0, elsewhere_ - inflow);
    // Anywhere on the route with probability jump.
    double total = elsewhere_;
    for (const double m : p_)
      total += m;
    const double share = eps * total / allPositions();  // one position, all speeds
    for (double& m : p_)
      m = (1.0 - eps) * m + share / v_count;
    elsewhere_ = (1.0 - eps) * elsewhere_ + share * (allPositions() - x_count);
  }
}

void RoutePosterior::moveTo(int first, int width)
{
  const int lo = std::max(0, first), hi = std::min(keyframes_, first + width);
  if (hi <= lo || (lo == lo_ && hi == hi_))
    return;
  const int v_count = speeds(), old_count = positions();
  const int old_first = 2 * lo_, old_last = 2 * (hi_ - 1);
  const double density = outsideDensity();  // one position outside the old window, all speeds
  const int new_count = 2 * (hi - lo) - 1;
  next_.assign(static_cast<size_t>(v_count) * new_count, 0.0);
  double dropped = 0.0;  // what the old window held and the new does not
  for (int x = old_first; x <= old_last; ++x)
    if (x < 2 * lo || x > 2 * (hi - 1))
      for (int v = 0; v < v_count; ++v)
        dropped += p_[static_cast<size_t>(v) * old_count + x - old_first];
  for (int x = 0; x < new_count; ++x)
  {
    const int absolute = 2 * lo + x;
    if (absolute >= old_first && absolute <= old_last)
    {
      for (int v = 0; v < v_count; ++v)
        next_[static_cast<size_t>(v) * new_count + x] = p_[static_cast<size_t>(v) * old_count + absolute - old_first];
    }
    else
    {
      for (int v = 0; v < v_count; ++v)
        next_[static_cast<size_t>(v) * new_count + x] = density / v_count;
      elsewhere_ -= density;
    }
  }
  p_.swap(next_);
  lo_ = lo;
  hi_ = hi;
  elsewhere_ = positions() == allPositions() ? 0.0 : std::max(0.0, elsewhere_ + dropped);
}

void RoutePosterior::observe(const float* costs, const uint8_t* usable, int first, int width)
{
  if (keyframes_ < 1 || costs == nullptr)
    return;
  // The keyframes of the route the row covers: [lo, hi), entries j = k - first.
  const int lo = std::max(0, first), hi = std::min(keyframes_, first + width);
  if (hi <= lo)
    return;
  const auto used = [&](int k) { return (usable == nullptr || usable[k - first]) && std::isfinite(costs[k - first]); };
  // The usable costs' least and the likelihoods' median (the featureless keyframes' and the outside's).
  double least = std::numeric_limits<double>::infinity();
  for (int k = lo; k < hi; ++k)
    if (used(k))
      least = std::min(least, static_cast<double>(costs[k - first]));
  if (!std::isfinite(least))
    return;  // no evidence
  std::vector<double>& log_likelihood = log_likelihood_;  // [k - lo]
  std::vector<double>& usable_values = usable_values_;
  log_likelihood.assign(static_cast<size_t>(hi - lo), 0.0);
  usable_values.clear();
  for (int k = lo; k < hi; ++k)
    if (used(k))
    {
      log_likelihood[k - lo] = -(costs[k - first] - least) / params_.cost_scale;
      usable_values.push_back(log_likelihood[k - lo]);
    }
  const size_t middle = usable_values.size() / 2;
  std::nth_element(usable_values.begin(), usable_values.begin() + middle, usable_values.end());
  const double neutral = usable_values[middle];
  for (int k = lo; k < hi; ++k)
    if (!used(k))
      log_likelihood[k - lo] = neutral;

  moveTo(lo, hi - lo);
  const int v_count = speeds(), x_count = positions();
  for (int x = 0; x < x_count; ++x)
  {
    const int k = x / 2;  // [k - lo]: the window is [lo, hi)
    const double weight =
        std::exp(x % 2 == 0 ? log_likelihood[k] : 0.5 * (log_likelihood[k] + log_likelihood[k + 1]));
    for (int v = 0; v < v_count; ++v)
      p_[static_cast<size_t>(v) * x_count + x] *= weight;
  }
  elsewhere_ *= std::exp(neutral);
  normalize();
}

void RoutePosterior::normalize()
{
  double total = elsewhere_;
  for (const double m : p_)
    total += m;
  if (!(total > 0.0) || !std::isfinite(total))
  {
    reset(keyframes_, -1);  // nothing left to weigh (cannot happen with finite costs): anywhere
    return;
  }
  for (double& m : p_)
    m /= total;
  elsewhere_ /= total;
}

double RoutePosterior::positionMass(int x) const
{
  if (x < 0 || x >= allPositions())
    return 0.0;
  if (x < 2 * lo_ || x > 2 * (hi_ - 1))
    return outsideDensity();
  const int x_count = positions();
  double mass = 0.0;
  for (int v = 0; v < speeds(); ++v)
    mass += p_[static_cast<size_t>(v) * x_count + x - 2 * lo_];
  return mass;
}

double RoutePosterior::keyframeMass(int keyframe) const
{
  if (keyframe < 0 || keyframe >= keyframes_)
    return 0.0;
  return positionMass(2 * keyframe) + 0.5 * (positionMass(2 * keyframe - 1) + positionMass(2 * keyframe + 1));
}

double RoutePosterior::withinOne(int keyframe) const
{
  if (keyframe < 0 || keyframe >= keyframes_)
    return 0.0;
  return std::min(1.0, keyframeMass(keyframe - 1) + keyframeMass(keyframe) + keyframeMass(keyframe + 1));
}

int RoutePosterior::mostLikely() const
{
  int best = lo_;
  double best_mass = -1.0;
  for (int k = lo_; k < hi_; ++k)
  {
    const double mass = keyframeMass(k);
    if (mass > best_mass)
    {
      best_mass = mass;
      best = k;
    }
  }
  return best;
}

}  // namespace along_route_localization
