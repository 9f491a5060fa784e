// atex.Error and the JSON bridge.
#include <string>

#include "common.h"

namespace atex::python {

namespace {
PyObject* g_error_type = nullptr;  // atex.Error; owned by the module (a reference kept here)
}

void RegisterError(py::module_& m) {
  g_error_type = PyErr_NewExceptionWithDoc(
      "atex.Error",
      "An error reported by libatex.\n\n"
      "Attributes:\n"
      "    code: the libatex status number (atex/status.h, format_spec/atex.md section 11),\n"
      "          e.g. 6 for a checksum mismatch.\n"
      "    name: its stable short name, e.g. 'checksum-mismatch'.\n"
      "    message: what went wrong and where (file, chunk, byte offset, element).\n"
      "str(error) is 'E<code> <name>: <message>'.",
      PyExc_Exception, nullptr);
  if (g_error_type == nullptr) throw py::error_already_set();
  m.add_object("Error", py::handle(g_error_type));
  py::dict codes;
  for (int c = 0; c <= static_cast<int>(StatusCode::kInternal); ++c) {
    codes[py::str(std::string(StatusCodeName(static_cast<StatusCode>(c))))] = c;
  }
  m.attr("STATUS_CODES") = codes;
}

void ThrowStatus(const Status& status) {
  py::object type = py::reinterpret_borrow<py::object>(py::handle(g_error_type));
  py::object error = type(status.ToString());
  error.attr("code") = static_cast<int>(status.code());
  error.attr("name") = std::string(StatusCodeName(status.code()));
  error.attr("message") = status.message();
  PyErr_SetObject(g_error_type, error.ptr());
  throw py::error_already_set();
}

py::object JsonToPython(const nlohmann::json& json) {
  py::object loads = py::module_::import("json").attr("loads");  // not static: no Python object outlives the interpreter
  return loads(json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
}

nlohmann::json PythonToJson(py::handle object) {
  py::object dumps = py::module_::import("json").attr("dumps");
  const std::string text = py::str(dumps(object));
  nlohmann::json out = nlohmann::json::parse(text, nullptr, false);
  if (out.is_discarded()) ThrowStatus(MakeError(StatusCode::kInvalidArgument, "not JSON-serialisable: ", text));
  return out;
}

}  // namespace atex::python
