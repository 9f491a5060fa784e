// SmallestFittingCount (count_search.h).
#include "count_search.h"

#include <algorithm>
#include <cmath>

namespace atex::fit::internal {

StatusOr<uint64_t> SmallestFittingCount(uint64_t lo, uint64_t lo_bytes, uint64_t hi, uint64_t hi_bytes, uint64_t budget,
                                        const std::function<StatusOr<uint64_t>(uint64_t)>& bytes_at, int* trials,
                                        uint64_t enough_slack) {
  if (!(lo < hi && lo_bytes > budget && hi_bytes <= budget)) {
    return MakeError(StatusCode::kInternal, "count search: the ends (", lo, ": ", lo_bytes, " bytes, ", hi, ": ",
                     hi_bytes, " bytes) do not bracket the budget of ", budget);
  }
  // An interpolated guess that does not halve the interval is followed by a bisection step, so
  // every two trials at least halve it: at most about twice a bisection's trials.
  bool bisect = false;
  int count = 0;
  // The guesses aim at the middle of the sizes accepted at once, [budget - enough_slack,
  // budget], not at its top: a guess off by compression noise or the sizes' curvature then
  // lands inside it as often from above as from below, instead of over the budget half the time.
  // On near-linear sizes this halves the trials (StopsOnceTheSlackLeftIsBelowEnough).
  const uint64_t aim = budget - std::min(enough_slack, budget) / 2;
  while (hi - lo > 1 && budget - hi_bytes >= enough_slack) {
    const uint64_t width = hi - lo;
    uint64_t next = lo + width / 2;
    if (!bisect) {
      // Where the straight line between the ends crosses the aim (rounded up, towards hi).
      // In the loop hi_bytes <= budget - enough_slack <= aim <= budget < lo_bytes: f is in (0, 1].
      const double f = static_cast<double>(lo_bytes - aim) / static_cast<double>(lo_bytes - hi_bytes);
      const double step = std::ceil(f * static_cast<double>(width));
      next = lo + static_cast<uint64_t>(std::clamp(step, 1.0, static_cast<double>(width - 1)));
    }
    ATEX_ASSIGN_OR_RETURN(const uint64_t bytes, bytes_at(next));
    ++count;
    if (bytes <= budget) {
      hi = next;
      hi_bytes = bytes;
    } else {
      lo = next;
      lo_bytes = bytes;  // > budget >= hi_bytes: the line keeps a positive slope
    }
    bisect = !bisect && (hi - lo) * 2 > width;
  }
  if (trials != nullptr) *trials = count;
  return hi;
}

}  // namespace atex::fit::internal
