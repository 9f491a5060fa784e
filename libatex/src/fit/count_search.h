// The smallest count of a divisible move whose output fits a budget (ApplyPlan's last move,
// the moves RefillSlack undoes in part). Not part of the public API.
#pragma once

#include <cstdint>
#include <functional>

#include "atex/status.h"

namespace atex::fit::internal {

// The smallest count in (lo, hi] whose encoded size fits `budget`, given the sizes at the
// ends: `lo_bytes` > budget (lo does not fit) and `hi_bytes` <= budget (hi fits). `bytes_at`
// encodes the output with one count and returns its exact size; the caller keeps what it
// needs of the fitting trials (the last fitting trial is always the answer's, unless the
// answer is `hi` itself, which is never tried).
//
// Sizes fall almost linearly with a move's count (each unit removes a Gaussian or a texture
// axis), so the next count tried is interpolated between the ends, aimed at the middle of the
// sizes accepted at once (budget - enough_slack / 2; the budget itself when enough_slack is 0).
// A bisection of a Panoptic texture move (36,000 textures) takes 16 encodes; on near-linear
// sizes with compression noise this search takes at most 8
// (CountSearch.FindsTheBoundaryOfMonotoneSizesInFewTrials). A guess that does not halve the
// interval (sizes far from linear) is followed by a bisection step, so the search never takes
// more than about twice a bisection's encodes. Like the bisection it replaces, it assumes sizes
// do not rise with the count; where they do locally, it returns a count that fits whose
// predecessor does not.
//
// `enough_slack` ends the search early: once a fitting count leaves fewer than that many bytes
// of the budget unused (budget - its size < enough_slack), it is the answer, though a smaller
// count may fit too. Near the boundary the sizes are mostly compression noise: the Panoptic
// uniform fit's refill took 15 whole-file encodes (2.1 s on an H100) to land 456 bytes under a
// 38 MB budget. With 0 the answer is the exact smallest fitting count. hi itself counts: when
// hi_bytes is less than `enough_slack` under the budget, nothing is tried.
//
// Errors: kInternal when the ends do not bracket the budget as stated (a bug of the caller);
// an error of `bytes_at` comes back as it is.
StatusOr<uint64_t> SmallestFittingCount(uint64_t lo, uint64_t lo_bytes, uint64_t hi, uint64_t hi_bytes, uint64_t budget,
                                        const std::function<StatusOr<uint64_t>(uint64_t)>& bytes_at,
                                        int* trials = nullptr, uint64_t enough_slack = 0);

// The slack below a budget that ApplyPlan's searches accept as spent (`enough_slack` above, and
// where the refill stops): less than 1/1024 of the budget. A user who asks for a budget gets a
// file within 0.1 % of it (or the exact smallest fitting count when that leaves more), and the
// searches stop chasing compression noise.
inline uint64_t EnoughSlack(uint64_t budget) { return budget / 1024; }

}  // namespace atex::fit::internal
