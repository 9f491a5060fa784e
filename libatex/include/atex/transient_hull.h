// Fast-object seeds: time-local Gaussians (docs/conventions.md §3, "Time-local Gaussians")
// where a multi-view dataset's foreground masks show something at one time only, such as a
// ball in flight. A deformation field learns motion from photometric gradients, which only
// reach a Gaussian inside its footprint, so an object that moves by more than its size
// between frames is lost in the frames where it flies (issue 20: the basketball). Each seed
// is a Gaussian placed where the object is at one timestep and visible around that time
// only; the field still deforms it, and densification clones it with its window.
//
// Rule (no constant is fitted to a scene): carve the visual hull of every timestep (the
// hull rule of atex/init.h: min_views, hull_keep_fraction) in the union of the per-time
// foreground boxes; a voxel's presence is the share of timesteps whose hull holds it. A
// voxel is transient at time t when the hull of t holds it and its presence is at most
// `max_presence`: a still or slow body occupies its voxels in most frames, a fast object
// in one or two. Seeds are drawn uniformly over the (timestep, transient voxel) pairs,
// jittered inside the voxel and re-tested with the hull rule; colour = the mean of the
// pixels they project to inside the masks of their timestep; scale = the RMS distance to
// the 3 nearest seeds of the same timestep; opacity `initial_opacity`; window centre = the
// timestep's time, inverse width = 1 / (window_frames · the median frame interval).
#pragma once

#include <array>
#include <cstddef>

#include "atex/dataset.h"
#include "atex/init.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

struct TransientSeedOptions {
  int points = 20000;          // seeds over all timesteps, at most
  int hull_resolution = 96;    // voxels along the longest side of the foreground box
  double max_presence = 0.25;  // share of timesteps, (0, 1)
  double window_frames = 0.5;  // window width 1/k in frame intervals, > 0
};

struct TransientSeedReport {
  int timesteps = 0;          // timesteps with enough masked training views
  size_t voxels = 0;          // of the fine grid
  size_t transient = 0;       // (timestep, voxel) pairs that passed the rule
  size_t seeds = 0;           // Gaussians returned
  double frame_interval = 0;  // median time between consecutive timesteps
  std::array<float, 3> box_min{0, 0, 0}, box_max{0, 0, 0};
};

// The seeds of `dataset` (training views with masks, grouped by timestep), with
// init.min_views, init.hull_keep_fraction, init.seed, init.sh_degree,
// init.initial_opacity and init.knn_neighbors from `init`. Returns Gaussians with
// time_windows set (possibly none: a scene without transient foreground gets an empty set).
// kInvalidArgument for options out of range or a dataset without timesteps; kNotFound when
// fewer than two timesteps have init.min_views masked training views.
StatusOr<Gaussians> TransientSeeds(const Dataset& dataset, const InitOptions& init, const TransientSeedOptions& options,
                                   TransientSeedReport* report = nullptr);

}  // namespace atex
