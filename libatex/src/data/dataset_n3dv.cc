// Neural 3D Video (N3DV / DyNeRF) scenes after frame extraction:
//   poses_bounds.npy    [cameras][17]: a 3x5 row-major LLFF pose [R | t | (H, W, focal)]
//                       followed by (near, far); row i belongs to the i-th camera folder
//   cam00/, cam01/, ... one folder per camera (sorted by name), holding the frames as
//                       cam00/images/0000.png (4DGaussians' extraction) or directly as
//                       cam00/0000.png; .png/.jpg/.jpeg, sorted by file name
//   or, without camera folders, the released videos cam00.mp4, cam01.mp4, ... (sorted;
//                       decoded with FFmpeg when the build has it, video_frames.h)
// Frame f of F (the smallest count over the cameras) has time f/(F-1). The
// focal length is scaled from the pose's (H, W) to the extracted frames' size;
// the principal point is the image centre. Camera 0 (cam00) is the test camera.
// Videos are decoded once when the dataset opens: the first max_timesteps frames of each
// (all without a limit), downscaled, kept in memory as 8-bit RGB; more bytes than
// image_cache_bytes are refused (kLimitExceeded) as soon as the decoding passes them.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include "atex/npy.h"
#include "data/dataset_loaders.h"
#include "data/video_frames.h"

namespace atex::data_detail {
namespace {

namespace fs = std::filesystem;

bool IsFrameFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

// Sorted frame files of one camera folder (images/ subfolder first).
std::vector<std::string> ListFrames(const fs::path& camera_dir) {
  std::vector<std::string> frames;
  for (const fs::path& dir : {camera_dir / "images", camera_dir}) {
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) continue;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      if (entry.is_regular_file(ec) && IsFrameFile(entry.path())) frames.push_back(entry.path().string());
    }
    if (!frames.empty()) break;
  }
  std::sort(frames.begin(), frames.end());
  return frames;
}

class N3dvDataset final : public Dataset {
 public:
  N3dvDataset(const std::string& folder, const DatasetOptions& options)
      : Dataset(DatasetNameFromPath(folder), DatasetKind::kN3dv, options), root_(folder) {}

  Status Load(const DatasetOptions& options) {
    const std::string poses_path = (root_ / "poses_bounds.npy").string();
    ATEX_ASSIGN_OR_RETURN(const NpyArray poses_array, ReadNpyFile(poses_path));
    if (poses_array.shape.size() != 2 || poses_array.shape[1] != 17 || poses_array.shape[0] < 1) {
      return MakeError(StatusCode::kCorrupt, poses_path, ": expected shape (cameras, 17)");
    }
    const size_t cameras = static_cast<size_t>(poses_array.shape[0]);
    const std::vector<double> poses = poses_array.ToDouble();  // [cameras][17]

    std::vector<fs::path> camera_dirs, camera_videos;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(root_, ec)) {
      std::string name = entry.path().filename().string();
      const bool video = entry.is_regular_file(ec) && entry.path().extension() == ".mp4";
      if (video) name = entry.path().stem().string();
      if ((video || entry.is_directory(ec)) && name.size() > 3 && name.compare(0, 3, "cam") == 0 &&
          std::all_of(name.begin() + 3, name.end(), [](unsigned char c) { return std::isdigit(c); })) {
        (video ? camera_videos : camera_dirs).push_back(entry.path());
      }
    }
    std::sort(camera_dirs.begin(), camera_dirs.end());
    std::sort(camera_videos.begin(), camera_videos.end());
    // Extracted frames take precedence (4DGaussians keeps them beside the videos).
    const bool from_video = camera_dirs.empty() && !camera_videos.empty();
    const std::vector<fs::path>& sources = from_video ? camera_videos : camera_dirs;
    if (sources.size() != cameras) {
      return MakeError(StatusCode::kCorrupt, root_.string(), ": poses_bounds.npy has ", cameras,
                       " cameras but there are ", sources.size(), from_video ? " camNN.mp4 videos" : " camNN folders");
    }

    std::vector<std::vector<std::string>> frames(cameras);
    size_t frame_count = SIZE_MAX, most = 0;
    ImageInfo info;
    if (from_video) {
      ATEX_ASSIGN_OR_RETURN(info, DecodeVideos(camera_videos, options, &frame_count, &most));
    } else {
      for (size_t c = 0; c < cameras; ++c) {
        frames[c] = ListFrames(camera_dirs[c]);
        frame_count = std::min(frame_count, frames[c].size());
        most = std::max(most, frames[c].size());
      }
      if (frame_count == 0) {
        return MakeError(StatusCode::kNotFound, root_.string(),
                         ": a camera folder has no frames (expected camNN/images/*.png or camNN/*.png)");
      }
      ATEX_ASSIGN_OR_RETURN(info, ReadImageInfo(frames[0][0]));
    }
    if (most > frame_count) {
      warnings_.push_back(StrCat("n3dv: cameras have between ", frame_count, " and ", most, " frames; using the first ",
                                 frame_count));
    }
    if (options.max_timesteps > 0) frame_count = std::min<size_t>(frame_count, options.max_timesteps);
    timestep_count_ = static_cast<int>(frame_count);

    const std::vector<int> test_ids = options.test_cameras.empty() ? std::vector<int>{0} : options.test_cameras;
    for (int id : test_ids) {
      if (id < 0 || static_cast<size_t>(id) >= cameras) {
        return MakeError(StatusCode::kNotFound, root_.string(), ": test camera ", id, " (the scene has ", cameras, ")");
      }
    }
    const std::set<int> test_set(test_ids.begin(), test_ids.end());

    double nearest = INFINITY, farthest = 0;
    for (size_t c = 0; c < cameras; ++c) {
      const double* row = poses.data() + c * 17;
      if (row[15] > 0 && row[16] > row[15] && std::isfinite(row[16])) {
        nearest = std::min(nearest, row[15]);
        farthest = std::max(farthest, row[16]);
      }
      const double pose_h = row[4], pose_w = row[9], focal = row[14];
      if (!(pose_h > 0 && pose_w > 0 && focal > 0) || !std::isfinite(pose_h + pose_w + focal)) {
        return MakeError(StatusCode::kCorrupt, poses_path, ": camera ", c, ": invalid (H, W, focal) = (", pose_h,
                         ", ", pose_w, ", ", focal, ")");
      }
      if (std::abs(pose_h / pose_w - double(info.height) / info.width) > 0.01 * pose_h / pose_w) {
        warnings_.push_back(StrCat("n3dv: camera ", c, ": frames are ", info.width, "x", info.height,
                                   " but the poses say ", pose_w, "x", pose_h, " (aspect differs)"));
      }
      StatusOr<std::array<double, 16>> w2c = LlffPoseToOpenCv(row);
      if (!w2c.ok()) return w2c.status().WithContext(StrCat(poses_path, ": camera ", c));
      Camera base;
      base.width = info.width;
      base.height = info.height;
      base.fx = base.fy = focal * info.width / pose_w;
      base.cx = 0.5 * info.width;
      base.cy = 0.5 * info.height;
      base.world_to_camera = *w2c;
      base = ScaleCamera(base, downscale_);
      if (base.width < 1 || base.height < 1) {
        return MakeError(StatusCode::kInvalidArgument, root_.string(), ": downscale ", downscale_, " leaves no pixels");
      }
      const bool is_test = test_set.count(static_cast<int>(c)) > 0;
      for (size_t f = 0; f < frame_count; ++f) {
        View view;
        view.camera = base;
        view.camera.time = frame_count > 1 ? double(f) / double(frame_count - 1) : 0.0;
        view.camera.name = StrCat(sources[c].stem().string(), " / frame ", f);
        view.camera_id = static_cast<int>(c);
        view.timestep = static_cast<int>(f);
        if (from_video) {
          view.image = camera_videos[c].string();
          view.frame_index = static_cast<int>(c * video_frames_per_camera_ + f);
        } else {
          view.image = frames[c][f];
        }
        (is_test ? test_ : train_).push_back(std::move(view));
      }
    }
    if (farthest > 0) depth_bounds_ = {static_cast<float>(nearest), static_cast<float>(farthest)};
    FinishTimeRange(train_, test_, &time_min_, &time_max_);
    return Status::Ok();
  }

 protected:
  StatusOr<Image> ReadViewImage(const View& view) const override {
    if (view.frame_index < 0) return ReadImage(view.image);
    const VideoFrame& frame = video_frames_.at(view.frame_index);
    Image image(frame.width, frame.height, 3);
    for (size_t k = 0; k < frame.rgb.size(); ++k) image.pixels[k] = frame.rgb[k] / 255.0f;
    return image;
  }

 private:
  struct VideoFrame {
    int width = 0, height = 0;
    std::vector<uint8_t> rgb;  // [H][W][3], already downscaled
  };

  // Decodes the first max_timesteps frames (all without a limit) of every video, downscaled,
  // into video_frames_ (camera-major, video_frames_per_camera_ slots each). The full-size
  // frame info of the first video, and the smallest / largest frame counts.
  StatusOr<ImageInfo> DecodeVideos(const std::vector<fs::path>& videos, const DatasetOptions& options,
                                   size_t* fewest, size_t* most) {
    if (!VideoDecodingAvailable()) {
      return MakeError(
          StatusCode::kUnsupported, root_.string(),
          ": N3DV from camNN.mp4 needs FFmpeg and this build is without FFmpeg (install "
          "libavformat-dev libavcodec-dev libswscale-dev libavutil-dev and rebuild), or extract the frames "
          "first: "
          "ffmpeg -i cam00.mp4 cam00/images/%04d.png for each camera");
    }
    images_prescaled_ = true;
    ImageInfo info;
    std::vector<std::vector<VideoFrame>> decoded(videos.size());
    uint64_t bytes = 0;
    for (size_t c = 0; c < videos.size(); ++c) {
      const std::string path = videos[c].string();
      StatusOr<int64_t> count =
          DecodeVideoFrames(path, options.max_timesteps, [&](int64_t index, Image full) -> Status {
            if (c == 0 && index == 0) info = ImageInfo{full.width, full.height, 3};
            if (full.width != info.width || full.height != info.height) {
              return MakeError(StatusCode::kCorrupt, path, ": frame ", index, " is ", full.width, "x", full.height,
                               ", the first camera's frames are ", info.width, "x", info.height);
            }
            ATEX_ASSIGN_OR_RETURN(const Image small, DownscaleImage(full, downscale_));
            bytes += small.pixels.size();
            if (bytes > options.image_cache_bytes) {
              return MakeError(
                  StatusCode::kLimitExceeded, path, ": decoded frames need more than the image cache's ",
                  options.image_cache_bytes >> 20, " MiB at frame ", index,
                  " (decoded videos stay in memory: use --timesteps or --downscale, or extract the frames)");
            }
            VideoFrame frame{small.width, small.height, std::vector<uint8_t>(small.pixels.size())};
            for (size_t k = 0; k < small.pixels.size(); ++k) {
              frame.rgb[k] = static_cast<uint8_t>(std::lround(std::clamp(small.pixels[k], 0.0f, 1.0f) * 255.0f));
            }
            decoded[c].push_back(std::move(frame));
            return Status::Ok();
          });
      if (!count.ok()) return count.status();
    }
    *fewest = SIZE_MAX;
    *most = 0;
    for (const auto& frames : decoded) {
      *fewest = std::min(*fewest, frames.size());
      *most = std::max(*most, frames.size());
    }
    video_frames_per_camera_ = *most;
    for (auto& frames : decoded) {
      frames.resize(*most);
      for (VideoFrame& frame : frames) video_frames_.push_back(std::move(frame));
    }
    return info;
  }

  fs::path root_;
  std::vector<VideoFrame> video_frames_;
  size_t video_frames_per_camera_ = 0;
};

}  // namespace

StatusOr<std::unique_ptr<Dataset>> OpenN3dv(const std::string& folder, const DatasetOptions& options) {
  auto dataset = std::make_unique<N3dvDataset>(folder, options);
  ATEX_RETURN_IF_ERROR(dataset->Load(options));
  return std::unique_ptr<Dataset>(std::move(dataset));
}

}  // namespace atex::data_detail
