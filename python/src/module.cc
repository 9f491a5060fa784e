// The `atex._atex` extension module (python/atex/__init__.py re-exports it). The API follows
// the C++ library (atex/*.h), not the command line; docs/python.md describes it.
#include <pybind11/pybind11.h>

#include "atex/container.h"
#include "atex/version.h"
#include "common.h"

PYBIND11_MODULE(_atex, m) {
  namespace py = pybind11;
  using namespace atex::python;
  m.doc() = "libatex bindings: read, write, deform, render, evaluate, fit and train AdaTex4D assets.";
  m.attr("__version__") = atex::kVersion;
  m.attr("FORMAT_VERSION") = py::make_tuple(atex::kFormatVersionMajor, atex::kFormatVersionMinor);
#ifdef ATEX_HAVE_CUDA
  m.attr("HAVE_CUDA") = true;
#else
  m.attr("HAVE_CUDA") = false;
#endif
  m.attr("HAVE_DRACO") = atex::HaveDracoCodec();
  RegisterError(m);
  RegisterTensor(m);
  RegisterAsset(m);
  RegisterRender(m);
  RegisterFitTrain(m);
  RegisterExport(m);
}
