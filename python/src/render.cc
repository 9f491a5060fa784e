// atex.Camera, atex.Dataset, atex.render and atex.eval, through a training backend (the
// CPU reference engine, or CUDA where built and a device is present).
#include <pybind11/stl.h>

#include <string>
#include <utility>

#include "atex/dataset.h"
#include "atex/render.h"
#include "atex/train/trainer.h"
#include "common.h"
#include "dlpack.h"
#ifdef ATEX_HAVE_CUDA
#include "atex/cuda/cuda_backend.h"
#endif

namespace atex::python {

using DatasetPtr = std::shared_ptr<Dataset>;

StatusOr<std::unique_ptr<train::Backend>> MakeBackend(const std::string& name, std::string* description) {
  if (name != "cpu" && name != "cuda" && name != "auto") {
    return MakeError(StatusCode::kInvalidArgument, "unknown backend '", name, "' (auto, cuda, cpu)");
  }
#ifdef ATEX_HAVE_CUDA
  if (name != "cpu") {
    std::string why;
    if (cuda::DeviceAvailable(&why)) {
      *description = "cuda: " + cuda::DeviceDescription();
      return cuda::MakeCudaBackend();
    }
    if (name == "cuda") return MakeError(StatusCode::kNoDevice, "no usable CUDA device (", why, ")");
  }
#else
  if (name == "cuda") {
    return MakeError(StatusCode::kNoDevice, "this build of the atex module has no CUDA backend; use backend='cpu'");
  }
#endif
  *description = "cpu (reference engine)";
  return train::MakeCpuBackend();
}

StatusOr<AssetHolder::LoadedBackend*> BackendFor(AssetHolder& holder, const std::string& name) {
  std::lock_guard<std::mutex> lock(holder.backends_mutex);
  for (auto& b : holder.backends) {
    if (b->name == name) return b.get();
  }
  auto loaded = std::make_unique<AssetHolder::LoadedBackend>();
  loaded->name = name;
  ATEX_ASSIGN_OR_RETURN(loaded->backend, MakeBackend(name, &loaded->description));
  ATEX_RETURN_IF_ERROR(loaded->backend->Load(train::RenderStateFromAsset(holder.asset)));
  holder.backends.push_back(std::move(loaded));
  return holder.backends.back().get();
}

namespace {

py::object ImageToTensor(Image image, bool as_tensor) {
  auto owner = std::make_shared<Image>(std::move(image));
  TensorData t;
  t.data = owner->pixels.data();
  t.shape = {owner->height, owner->width, owner->channels};
  t.owner = owner;
  py::object tensor = MakeTensor(std::move(t));
  return as_tensor ? tensor : tensor.attr("numpy")();
}

DatasetPtr OpenDatasetPy(const std::string& path, const std::string& kind, int timesteps, int downscale,
                         std::vector<int> test_cameras) {
  DatasetOptions o;
  o.kind = ValueOrThrow(ParseDatasetKind(kind));
  o.max_timesteps = timesteps;
  o.downscale = downscale;
  o.test_cameras = std::move(test_cameras);
  StatusOr<std::unique_ptr<Dataset>> opened = Status(StatusCode::kInternal, "not opened");
  {
    py::gil_scoped_release release;
    opened = OpenDataset(path, o);
  }
  return DatasetPtr(ValueOrThrow(std::move(opened)));
}

DatasetPtr AsDataset(py::handle dataset) {
  if (py::isinstance<py::str>(dataset)) return OpenDatasetPy(dataset.cast<std::string>(), "auto", 0, 1, {});
  if (py::hasattr(dataset, "__fspath__")) return OpenDatasetPy(py::str(dataset.attr("__fspath__")()), "auto", 0, 1, {});
  return dataset.cast<DatasetPtr>();
}

void RegisterCamera(py::module_& m) {
  py::class_<Camera>(m, "Camera",
                     "A pinhole camera in the OpenCV convention (atex/camera.h): x right, y down, z forward;\n"
                     "pixel (i, j) has its centre at (i + 0.5, j + 0.5); world_to_camera is a row-major 4x4 rigid\n"
                     "transform; time is the scene time of the view.")
      .def(py::init([](int width, int height, double fx, double fy, double cx, double cy,
                       std::array<double, 16> world_to_camera, double time, std::string name) {
             Camera c;
             c.width = width;
             c.height = height;
             c.fx = fx;
             c.fy = fy;
             c.cx = cx;
             c.cy = cy;
             c.world_to_camera = world_to_camera;
             c.time = time;
             c.name = std::move(name);
             return c;
           }),
           py::arg("width"), py::arg("height"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
           py::arg("world_to_camera") = std::array<double, 16>{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1},
           py::arg("time") = 0.0, py::arg("name") = "",
           "world_to_camera: 16 numbers, row-major (a flattened 4x4 numpy array works).")
      .def_readwrite("width", &Camera::width)
      .def_readwrite("height", &Camera::height)
      .def_readwrite("fx", &Camera::fx)
      .def_readwrite("fy", &Camera::fy)
      .def_readwrite("cx", &Camera::cx)
      .def_readwrite("cy", &Camera::cy)
      .def_readwrite("world_to_camera", &Camera::world_to_camera)
      .def_readwrite("time", &Camera::time)
      .def_readwrite("name", &Camera::name)
      .def_property_readonly("center", &Camera::Center, "Camera centre in world coordinates.")
      .def("__repr__", [](const Camera& c) {
        return "atex.Camera(" + std::to_string(c.width) + "x" + std::to_string(c.height) + ", t=" +
               std::to_string(c.time) + (c.name.empty() ? "" : ", '" + c.name + "'") + ")";
      });

  py::class_<View>(m, "View", "One view of a dataset: its camera (time included), camera id and timestep.")
      .def_readonly("camera", &View::camera)
      .def_readonly("camera_id", &View::camera_id)
      .def_readonly("timestep", &View::timestep)
      .def_readonly("image_path", &View::image)
      .def("__repr__", [](const View& v) {
        return "atex.View(camera_id=" + std::to_string(v.camera_id) + ", t=" + std::to_string(v.camera.time) + ")";
      });

  py::class_<Dataset, DatasetPtr>(m, "Dataset",
                                  "A multi-view video dataset (atex/dataset.h): CMU Panoptic, D-NeRF, the tiny lego\n"
                                  ".npz, Neural 3D Video. Images are decoded on first use and cached.")
      .def(py::init(&OpenDatasetPy), py::arg("path"), py::arg("kind") = "auto", py::arg("timesteps") = 0,
           py::arg("downscale") = 1, py::arg("test_cameras") = std::vector<int>{},
           "Opens a dataset folder or the lego .npz (kind: auto, panoptic, dnerf, dnerf-npz, n3dv, nerfstudio, colmap).")
      .def_property_readonly("name", &Dataset::name)
      .def_property_readonly("kind", [](const Dataset& d) { return std::string(DatasetKindName(d.kind())); })
      .def_property_readonly("train_views", &Dataset::train_views)
      .def_property_readonly("test_views", &Dataset::test_views)
      .def_property_readonly("timestep_count", &Dataset::timestep_count)
      .def_property_readonly("time_range", [](const Dataset& d) { return py::make_tuple(d.time_min(), d.time_max()); })
      .def_property_readonly("background", &Dataset::background)
      .def_property_readonly("warnings", &Dataset::warnings)
      .def("image", [](const DatasetPtr& d, const View& view) {
        StatusOr<std::shared_ptr<const Image>> image = Status(StatusCode::kInternal, "not loaded");
        {
          py::gil_scoped_release release;
          image = d->LoadImage(view);
        }
        std::shared_ptr<const Image> owner = ValueOrThrow(std::move(image));
        TensorData t;
        t.data = const_cast<float*>(owner->pixels.data());
        t.shape = {owner->height, owner->width, owner->channels};
        t.owner = owner;
        t.read_only = true;  // the dataset's cache holds the same image
        return MakeTensor(std::move(t)).attr("numpy")();
      }, py::arg("view"), "The view's image, [H, W, 3] float32 RGB in [0, 1] (shared with the cache, read-only).");
}

py::object Render(const AssetPtr& asset, const Camera& camera_in, py::object t, const std::string& backend,
                  py::object background, py::object near_plane, const std::string& output) {
  if (output != "numpy" && output != "tensor") {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "output must be 'numpy' or 'tensor', not '", output, "'"));
  }
  Camera camera = camera_in;
  if (!t.is_none()) camera.time = t.cast<double>();
  train::RenderRequest request = train::RenderRequestFor(asset->asset);
  if (!background.is_none()) request.background = background.cast<std::array<float, 3>>();
  if (!near_plane.is_none()) request.near_plane = near_plane.cast<float>();
  StatusOr<Image> image = Status(StatusCode::kInternal, "not rendered");
#ifdef ATEX_HAVE_CUDA
  // A tensor from the CUDA backend stays on the device (DLPack kDLCUDA): no copy to the host.
  StatusOr<cuda::DeviceImage> on_device = Status(StatusCode::kInternal, "not rendered");
  bool device_tensor = false;
#endif
  {
    py::gil_scoped_release release;
    auto loaded = BackendFor(*asset, backend);
    if (loaded.ok()) {
      std::lock_guard<std::mutex> lock((*loaded)->mutex);
#ifdef ATEX_HAVE_CUDA
      device_tensor = output == "tensor" && (*loaded)->description.rfind("cuda", 0) == 0;
      if (device_tensor) {
        on_device = cuda::RenderOnDevice(*(*loaded)->backend, camera, request);
      } else {
        image = (*loaded)->backend->Render(camera, request);
      }
#else
      image = (*loaded)->backend->Render(camera, request);
#endif
    } else {
      image = loaded.status();
    }
  }
#ifdef ATEX_HAVE_CUDA
  if (device_tensor) {
    cuda::DeviceImage rendered = ValueOrThrow(std::move(on_device));
    TensorData t;
    t.data = const_cast<float*>(rendered.pixels);
    t.shape = {rendered.height, rendered.width, 3};
    t.device = {dlpack::kCuda, rendered.device};
    t.owner = std::move(rendered.owner);
    return MakeTensor(std::move(t));
  }
#endif
  return ImageToTensor(ValueOrThrow(std::move(image)), output == "tensor");
}

py::object Eval(const AssetPtr& asset, py::handle dataset_arg, const std::string& split, const std::string& backend,
                py::object near_plane) {
  DatasetPtr dataset = AsDataset(dataset_arg);
  if (split != "test" && split != "train") {
    ThrowStatus(MakeError(StatusCode::kInvalidArgument, "split must be 'test' or 'train', not '", split, "'"));
  }
  train::RenderRequest request = train::RenderRequestFor(asset->asset);
  if (!near_plane.is_none()) request.near_plane = near_plane.cast<float>();
  StatusOr<train::EvalResult> result = Status(StatusCode::kInternal, "not evaluated");
  std::string description;
  {
    py::gil_scoped_release release;
    auto loaded = BackendFor(*asset, backend);
    if (loaded.ok()) {
      std::lock_guard<std::mutex> lock((*loaded)->mutex);
      description = (*loaded)->description;
      result = train::Evaluate(*dataset, *(*loaded)->backend,
                               split == "test" ? dataset->test_views() : dataset->train_views(), request);
    } else {
      result = loaded.status();
    }
  }
  const train::EvalResult eval = ValueOrThrow(std::move(result));
  nlohmann::json j = train::EvalToJson(eval);
  j["split"] = split;
  j["backend"] = description;
  return JsonToPython(j);
}

}  // namespace

DatasetPtr AsDatasetArg(py::handle dataset) { return AsDataset(dataset); }

void RegisterRender(py::module_& m) {
  RegisterCamera(m);
  m.def("render", &Render, py::arg("asset"), py::arg("camera"), py::arg("t") = py::none(), py::arg("backend") = "auto",
        py::arg("background") = py::none(), py::arg("near_plane") = py::none(), py::arg("output") = "numpy",
        "Renders `asset` seen by `camera` at scene time t (default: camera.time): the deformation, the textures,\n"
        "the full SH degree and the asset's background, as `atex render` does. Returns [H, W, 3] float32 RGB\n"
        "(values as rendered, not clamped): a numpy array, or with output='tensor' an atex.Tensor (DLPack):\n"
        "in host memory from the CPU backend, in device memory from the CUDA one (no copy to the host;\n"
        "torch.from_dlpack gives a CUDA tensor on the same memory).\n\n"
        "backend: 'auto' (CUDA when this build has it and a device is present, else the CPU reference),\n"
        "'cuda' or 'cpu'. The asset is loaded into the backend once and kept with the asset, so repeated\n"
        "renders of one asset pay only for the render. Runs without the GIL.");
  m.def("eval", &Eval, py::arg("asset"), py::arg("dataset"), py::arg("split") = "test", py::arg("backend") = "auto",
        py::arg("near_plane") = py::none(),
        "PSNR, SSIM, DSSIM1, DSSIM2 of `asset` on a dataset's test (or train) views, as `atex eval --json`:\n"
        "renders clamped to [0, 1] first (atex/train/trainer.h, Evaluate). dataset: an atex.Dataset or a path.\n"
        "Returns a dict with 'mean', per-'views' and per-'cameras' metrics.");
}

}  // namespace atex::python
