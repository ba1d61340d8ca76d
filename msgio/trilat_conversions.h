#ifndef ROOMFIX_MSGIO_TRILAT_CONVERSIONS_H_
#define ROOMFIX_MSGIO_TRILAT_CONVERSIONS_H_

#include <vector>

#include "core/trilat/trilateration.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"

namespace roomfix {

// The ranges of a range set as solver input (reuses *out's storage).
void RangesFromMessage(const range_set_t& set, std::vector<trilat::RangeMeasurement>* out);

// A fix as a pose2d_t (source ultrasound): valid at the firing time, heading
// unknown (NaN), covariance of (x, y) from the fix with the heading rows and
// columns NaN; status ok, degraded, or lost with NaN position when the fix
// has none.
pose2d_t PoseFromFix(const trilat::Fix& fix, const range_set_t& set, int32_t robot_id,
                     int64_t publish_utime);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_TRILAT_CONVERSIONS_H_
