// Baseline for step 4: SeqSLAM's straight-line sequence search, made causal for online use.
#ifndef ALONG_ROUTE_LOCALIZATION_SEQSLAM_H
#define ALONG_ROUTE_LOCALIZATION_SEQSLAM_H

#include "along_route_localization/cost_ring_buffer.h"
#include "along_route_localization/online_dtw.h"

namespace along_route_localization
{

/// SeqSLAM's straight-line search, kept as the baseline. Causal: every trajectory ends at the
/// current frame. For each end keyframe i and velocity v in [min_velocity, max_velocity] (step
/// velocity_step, keyframes per frame) the score is the mean of C_age(round(i - v * age)) over
/// age = 0 .. sequence_length - 1.
struct SeqSlamParams
{
  int sequence_length = 10;   ///< ds, frames
  float min_velocity = 0.8f;  ///< keyframes per frame
  float max_velocity = 1.25f;
  float velocity_step = 0.05f;
  float missing_cost = 1.0f;
  int exclusion_radius = 5;   ///< Rwindow of SeqSLAM, for second_cost
};

SequenceMatch seqSlamMatch(const CostRingBuffer& buffer, int first_end, int count,
                           const SeqSlamParams& params);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_SEQSLAM_H
