// SmallestFittingCount (count_search.h).
#include "count_search.h"

#include <algorithm>
#include <cmath>

namespace atex::fit::internal {

StatusOr<uint64_t> SmallestFittingCount(uint64_t lo, uint64_t lo_bytes, uint64_t hi, uint64_t hi_bytes,
                                        uint64_t budget, const std::function<StatusOr<uint64_t>(uint64_t)>& bytes_at,
                                        int* trials) {
  if (!(lo < hi && lo_bytes > budget && hi_bytes <= budget)) {
    return MakeError(StatusCode::kInternal, "count search: the ends (", lo, ": ", lo_bytes, " bytes, ", hi, ": ",
                     hi_bytes, " bytes) do not bracket the budget of ", budget);
  }
  int streak = 0;         // consecutive interpolated trials that moved the same end
  bool last_fit = false;  // which end the last trial moved
  int count = 0;
  while (hi - lo > 1) {
    const bool bisect = streak >= 2;  // the interpolation stalls on one side: bisect once
    uint64_t next = lo + (hi - lo) / 2;
    if (!bisect) {
      // Where the straight line between the ends crosses the budget (rounded up, towards hi).
      const double f = static_cast<double>(lo_bytes - budget) / static_cast<double>(lo_bytes - hi_bytes);
      const auto step = static_cast<uint64_t>(std::ceil(f * static_cast<double>(hi - lo)));
      next = std::clamp<uint64_t>(lo + step, lo + 1, hi - 1);
    }
    ATEX_ASSIGN_OR_RETURN(const uint64_t bytes, bytes_at(next));
    ++count;
    const bool fits = bytes <= budget;
    streak = bisect ? 0 : (streak > 0 && fits == last_fit ? streak + 1 : 1);
    last_fit = fits;
    if (fits) {
      hi = next;
      hi_bytes = bytes;
    } else {
      lo = next;
      // A size at or below the fitting end's (not monotone here): keep the line's slope positive.
      lo_bytes = std::max(bytes, hi_bytes + 1);
    }
  }
  if (trials != nullptr) *trials = count;
  return hi;
}

}  // namespace atex::fit::internal
