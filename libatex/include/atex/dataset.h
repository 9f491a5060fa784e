// Multi-view video datasets: cameras (OpenCV convention, conventions §1), times
// in [0, 1] (§8) and lazily loaded images.
//
// Layouts read:
//   kPanoptic  Dynamic3DGaussians' CMU Panoptic layout: train_meta.json and
//              test_meta.json ({w, h, k[t][i] 3x3, w2c[t][i] 4x4 OpenCV
//              world-to-camera, fn[t][i] "<cam>/<t>.jpg", cam_id[t][i]}),
//              ims/<fn>, seg/<fn as .png> (masks, train cameras). The metas' split
//              is kept (test: cameras 0, 10, 15, 30). Timesteps used: the longest
//              prefix 0..T-1 whose images exist for every camera (a warning says how
//              many listed timesteps were dropped); time = t/(T-1). Intrinsics as given.
//   kDNerf     D-NeRF / Blender: transforms_{train,test[,val]}.json with
//              camera_angle_x and frames {file_path (".png" added when it has no
//              extension), time, transform_matrix (c2w, Blender axes)}; fx = fy =
//              W/2/tan(camera_angle_x/2), principal point (W/2, H/2). Missing frames
//              are skipped with a warning. RGBA frames are composited on the
//              background; alpha > 0.5 is their mask.
//   kDNerfNpz  the tiny D-NeRF lego packed as one .npz: images (81,H,W,3) f32,
//              poses (81,4,4) c2w Blender, times (81,), focal; frames 0-49 train,
//              50-60 val, 61-80 test. Images stay in memory.
//   kN3dv      Neural 3D Video (DyNeRF release or after frame extraction): poses_bounds.npy
//              [cameras][17] (LLFF 3x5 [R | t | (H, W, focal)], rotation columns
//              (down, right, back), then near, far) and one folder per camera,
//              cam00, cam01, ... (sorted; row i = i-th folder), holding frames as
//              camNN/images/NNNN.png (4DGaussians' extraction) or camNN/NNNN.png
//              (.png/.jpg/.jpeg, sorted by name). F = the smallest frame count
//              (a warning when cameras differ); time = f/(F-1); focal scaled from the
//              pose's W to the frames' width, principal point at the centre; cam00 is
//              the test camera; depth_bounds() = (min near, max far). Without camera
//              folders, the released videos cam00.mp4, cam01.mp4, ... are decoded
//              (FFmpeg builds only; otherwise kUnsupported saying how to extract the
//              frames) once, at opening: the first max_timesteps frames of each, kept
//              downscaled in memory as 8-bit RGB within image_cache_bytes
//              (kLimitExceeded beyond it).
//   kNerfstudio Nerfstudio / instant-ngp: a transforms.json (the file, or the folder
//              holding it; atex/dataset_formats.h for its keys) with per-frame
//              transform_matrix (c2w, OpenGL axes, converted like D-NeRF's), global or
//              per-frame pinhole intrinsics (fl_x/fl_y/cx/cy/w/h or camera_angle_x;
//              non-zero distortion and non-pinhole models are refused, not undistorted),
//              per-frame `time` (or `timestep` / the largest timestep; else static,
//              time 0; rescaled to [0, 1] when outside), optional camera_id (then views
//              carry timesteps: the rank of their time), mask_path and ply_file_path
//              (point_cloud()). Split, first rule that applies: test_cameras (camera ids);
//              transforms_test.json beside the file; nerfstudio's test_filenames (else
//              val_filenames; train_filenames when given); else the frames sorted by
//              file_path of rank 0, 8, 16, ... are the test split.
//   kColmap    a static COLMAP model: cameras, images and points3D (.bin, else .txt) in
//              sparse/0/, sparse/ or the folder, frames in images/. Camera models
//              PINHOLE, SIMPLE_PINHOLE, and SIMPLE_RADIAL/RADIAL/OPENCV/FULL_OPENCV with
//              zero distortion (others: kUnsupported naming the camera and model). Time
//              0, no timesteps; every image its own camera (camera_id = rank by name).
//              Split: images sorted by name, ranks 0, 8, 16, ... test (LLFF / Mip-NeRF
//              360). points3D is point_cloud().
//   kAuto      chosen from what the path holds (.npz file; .json file; train_meta.json;
//              transforms_train.json; transforms.json; poses_bounds.npy; a COLMAP model).
//
// Images are decoded on first use and kept in a bounded, thread-safe LRU cache
// (DatasetOptions::image_cache_bytes), so a long multi-camera video never needs
// all its frames in memory. Downscaling by an integer factor is applied to
// images, masks and intrinsics consistently (image.h, DownscaleImage).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "atex/camera.h"
#include "atex/image.h"
#include "atex/status.h"

namespace atex {

class ImageCache;  // data/image_cache.h
struct InMemoryFrame;

enum class DatasetKind { kAuto, kPanoptic, kDNerf, kDNerfNpz, kN3dv, kNerfstudio, kColmap, kInMemory };

// The background a dataset kind's published results use, the default of
// DatasetOptions::background and of the training config: white for D-NeRF folders (RGBA
// frames, composited on white by D-NeRF and 4DGaussians' evaluation); black for the rest,
// including the tiny lego .npz, whose frames were stored with alpha dropped on black.
std::array<float, 3> DefaultBackground(DatasetKind kind);
// One line saying where that default comes from (for logs and reports).
std::string DefaultBackgroundReason(DatasetKind kind);

// "panoptic", "dnerf", "dnerf-npz", "n3dv", "nerfstudio", "colmap", "in-memory", "auto".
const char* DatasetKindName(DatasetKind kind);
// Inverse of DatasetKindName; kInvalidArgument for an unknown name.
StatusOr<DatasetKind> ParseDatasetKind(const std::string& name);

struct DatasetOptions {
  DatasetKind kind = DatasetKind::kAuto;
  int max_timesteps = 0;   // 0 = every timestep present; else the first max_timesteps (Panoptic, N3DV)
  int downscale = 1;       // integer factor >= 1
  uint64_t image_cache_bytes = uint64_t{2} << 30;
  // Camera ids to hold out for testing instead of the dataset's own split
  // (Panoptic: cam ids of either meta file; N3DV: camera index, default {0};
  // nerfstudio: the frames' camera_id). Not meaningful for D-NeRF or COLMAP
  // (kInvalidArgument when set).
  std::vector<int> test_cameras;
  // Background RGB that RGBA frames are composited on; default DefaultBackground(kind):
  // the dataset's published convention.
  std::optional<std::array<float, 3>> background;
  bool load_val_split = false;  // D-NeRF / lego .npz: also expose the val frames (val_views())
  // Stress settings (applied after the loader, to every layout; a warning says what was kept):
  // Keep every K-th timestep (1 = all): of the distinct timesteps loaded (after max_timesteps)
  // those of rank 0, K, 2K, ... are kept in both splits and renumbered 0..T'-1; times are
  // unchanged, so the scene moves K times as far between consecutive frames. Needs views
  // with timesteps (Panoptic, N3DV, in-memory); kInvalidArgument for D-NeRF.
  int timestep_stride = 1;
  // Train on N of the M training cameras (0 = all): of the distinct camera ids of the
  // training views, sorted ascending, ids[floor(i * M / N)] for i = 0..N-1 (deterministic,
  // evenly spaced). Test views are unchanged. D-NeRF: camera id = frame. kInvalidArgument if N > M.
  int train_cameras = 0;
};

struct View {
  Camera camera;        // intrinsics already scaled by DatasetOptions::downscale; camera.time = time
  int camera_id = -1;   // dataset camera number (Panoptic cam id, N3DV index); D-NeRF: frame index
  int timestep = -1;    // index of the frame's timestep (0 .. timestep_count()-1); D-NeRF: -1
  std::string image;    // image file path, or "<npz>:images[i]" for in-memory frames
  std::string mask;     // mask file path, empty when the view has no mask
  int frame_index = -1; // index into in-memory arrays (lego .npz, in-memory datasets); else -1
};

class Dataset {
 public:
  virtual ~Dataset() = default;
  Dataset(const Dataset&) = delete;
  Dataset& operator=(const Dataset&) = delete;

  const std::string& name() const { return name_; }
  DatasetKind kind() const { return kind_; }
  const std::vector<View>& train_views() const { return train_; }
  const std::vector<View>& test_views() const { return test_; }
  const std::vector<View>& val_views() const { return val_; }  // empty unless load_val_split
  int timestep_count() const { return timestep_count_; }
  float time_min() const { return time_min_; }
  float time_max() const { return time_max_; }
  std::array<float, 3> background() const { return background_; }
  // False when DatasetOptions::background chose it, true for DefaultBackground(kind()).
  bool background_is_default() const { return background_is_default_; }
  // Whether any decoded frame so far had an alpha channel (RGBA, grey + alpha); the
  // background only changes the images of such frames. Decodes the first training view
  // when none was decoded yet (errors count as "no alpha").
  bool frames_have_alpha() const;
  // Nearest and farthest scene depth seen by the cameras where the dataset
  // states them (N3DV's poses_bounds); {0, 0} when unknown.
  std::array<float, 2> depth_bounds() const { return depth_bounds_; }
  // True when LoadMask can succeed for (some) views.
  bool has_masks() const { return has_masks_; }
  // A point cloud file that comes with the dataset (COLMAP points3D, nerfstudio's
  // ply_file_path; atex/point_cloud.h reads it), in the cameras' world frame; empty when
  // none. The initialisation uses it by default (atex/init.h, kAuto).
  const std::string& point_cloud() const { return point_cloud_; }
  // Human-readable notes from opening (skipped frames, dropped timesteps); the CLI prints them.
  const std::vector<std::string>& warnings() const { return warnings_; }

  // The view's image as [H][W][3] RGB in [0, 1] (alpha composited on the
  // background), at the downscaled resolution. Cached; thread-safe. The shared
  // pointer stays valid after the cache evicts the entry.
  StatusOr<std::shared_ptr<const Image>> LoadImage(const View& view) const;
  // Foreground mask [H][W][1] in {0, 1} (Panoptic seg/; D-NeRF alpha > 0.5);
  // kNotFound where the view has none.
  StatusOr<std::shared_ptr<const Image>> LoadMask(const View& view) const;

  // Bytes of decoded images currently held by the cache (<= image_cache_bytes).
  uint64_t cache_bytes() const;
  uint64_t cache_limit() const { return cache_limit_; }

 protected:
  Dataset(std::string name, DatasetKind kind, const DatasetOptions& options);
  // Full-resolution image and mask of a view, as decoded (any channel count).
  virtual StatusOr<Image> ReadViewImage(const View& view) const = 0;
  virtual StatusOr<Image> ReadViewMask(const View& view) const;  // default: kNotFound

  // Filled by the loaders.
  std::string name_;
  DatasetKind kind_;
  std::vector<View> train_, test_, val_;
  int timestep_count_ = 0;
  float time_min_ = 0, time_max_ = 1;
  std::array<float, 3> background_{0, 0, 0};
  bool background_is_default_ = true;
  std::array<float, 2> depth_bounds_{0, 0};
  bool has_masks_ = false;
  // ReadViewImage returns images already downscaled (decoded videos kept small in memory).
  bool images_prescaled_ = false;
  std::string point_cloud_;
  int downscale_ = 1;
  std::vector<std::string> warnings_;

 private:
  friend StatusOr<std::unique_ptr<Dataset>> OpenDataset(const std::string& path, const DatasetOptions& options);
  friend StatusOr<std::unique_ptr<Dataset>> MakeInMemoryDataset(std::string name, std::vector<InMemoryFrame> frames,
                                                                const DatasetOptions& options);
  // DatasetOptions::timestep_stride and train_cameras, on the views the loader made.
  Status SelectViews(const DatasetOptions& options);

  void NoteAlpha(const Image& decoded) const;
  uint64_t cache_limit_;
  std::shared_ptr<ImageCache> cache_;
  mutable std::atomic<bool> alpha_known_{false}, alpha_seen_{false};
};

// The views of the earliest timestep among `views` (all of them when they have no timestep,
// as in D-NeRF): one view per camera in multi-view video, at the poses the cameras keep.
std::vector<const View*> FirstTimestepViews(const std::vector<View>& views);

// Opens a dataset folder (or the lego .npz file).
StatusOr<std::unique_ptr<Dataset>> OpenDataset(const std::string& path, const DatasetOptions& options = {});

// A dataset whose frames are already in memory (synthetic scenes, tests). Each
// frame's image is [H][W][1|3|4]; masks are [H][W][1] or empty. Time range and
// timestep count come from the views.
struct InMemoryFrame {
  View view;    // camera, camera_id, timestep; image/mask/frame_index are filled in
  Image image;
  Image mask;   // empty: no mask
  bool test = false;
};
StatusOr<std::unique_ptr<Dataset>> MakeInMemoryDataset(std::string name, std::vector<InMemoryFrame> frames,
                                                       const DatasetOptions& options = {});

// Camera conversions used by the loaders (exposed for tests and tools).
// Blender/NeRF camera-to-world (x right, y up, z back), row-major 4x4 -> OpenCV
// world-to-camera: (c2w · diag(1, −1, −1, 1))⁻¹. kCorrupt if the rotation is not
// orthonormal within 1e-3.
StatusOr<std::array<double, 16>> BlenderCameraToWorldToOpenCv(const std::array<double, 16>& c2w);
// LLFF pose rows (poses_bounds.npy: 3x5 row-major [R | t | hwf], rotation columns
// (down, right, back)) -> OpenCV world-to-camera.
StatusOr<std::array<double, 16>> LlffPoseToOpenCv(const double pose[15]);

}  // namespace atex
