#include "along_route_localization/seqslam.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace along_route_localization
{

SequenceMatch seqSlamMatch(const CostRingBuffer& buffer, int first_end, int count, const SeqSlamParams& params)
{
  if (params.sequence_length < 1 || params.velocity_step <= 0.0f || params.min_velocity > params.max_velocity)
    throw std::invalid_argument("SeqSlamParams: need sequence_length >= 1, velocity_step > 0, min <= max velocity");
  SequenceMatch result;
  const int rows = std::min(params.sequence_length, buffer.size());
  if (rows <= 0 || count <= 0)
    return result;
  const int velocities = static_cast<int>(std::floor((params.max_velocity - params.min_velocity) / params.velocity_step + 1e-4f)) + 1;
  std::vector<float> scores(count, std::numeric_limits<float>::infinity());
  for (int v_index = 0; v_index < velocities; ++v_index)
  {
    const float v = params.min_velocity + params.velocity_step * v_index;
    for (int i = 0; i < count; ++i)
    {
      const int end = first_end + i;
      float sum = 0.0f;
      for (int age = 0; age < rows; ++age)
        sum += buffer.at(age, static_cast<int>(std::lround(end - v * age)), params.missing_cost);
      scores[i] = std::min(scores[i], sum / rows);
    }
  }
  const int best = static_cast<int>(std::min_element(scores.begin(), scores.end()) - scores.begin());
  result.keyframe = first_end + best;
  result.cost = scores[best];
  result.rows = rows;
  result.second_cost = std::numeric_limits<float>::infinity();
  for (int i = 0; i < count; ++i)
  {
    if (std::abs(i - best) > params.exclusion_radius && scores[i] < result.second_cost)
    {
      result.second_cost = scores[i];
      result.has_second = true;
    }
  }
  if (!result.has_second)
    result.second_cost = result.cost;
  return result;
}

}  // namespace along_route_localization
