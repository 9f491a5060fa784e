// libFuzzer target: the .pth reader (atex/zip.h + the allow-list unpickler +
// tensor views) and the 4DGaussians field builder behind it.
//
// The first input byte picks how the rest is used:
//   even: the whole input is a deformation.pth archive;
//   odd:  the rest is a data.pkl pickle, wrapped here in a torch.save-style
//         archive with a few float storages, so the fuzzer reaches the
//         unpickler without having to forge zip records and CRCs.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/converters/fourdgs.h"
#include "atex/zip.h"

namespace {

void Exercise(const uint8_t* data, size_t size) {
  atex::TorchReadLimits limits;
  limits.max_elements = uint64_t{1} << 24;
  auto state = atex::ReadTorchStateDict(data, size, "fuzz.pth", limits);
  if (!state.ok()) return;
  for (int sh_coeffs : {1, 16}) {
    atex::FourDgsHeadFlags flags;
    flags.no_do = false;
    flags.no_dshs = false;
    (void)atex::FourDgsFieldFromStateDict(*state, flags, sh_coeffs, "fuzz.pth");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  if ((data[0] & 1) == 0) {
    Exercise(data + 1, size - 1);
    return 0;
  }
  atex::ZipWriter zip;
  if (!zip.Add("archive/data.pkl", data + 1, size - 1, false).ok()) return 0;
  // Storages "0".."3" of 1, 4, 16 and 64 float32 values (numel must match).
  for (int k = 0; k < 4; ++k) {
    const std::vector<uint8_t> raw(static_cast<size_t>(4) << (2 * k), 0x3f);
    if (!zip.Add("archive/data/" + std::to_string(k), raw.data(), raw.size(), false).ok()) return 0;
  }
  const std::vector<uint8_t> archive = zip.Finish();
  Exercise(archive.data(), archive.size());
  return 0;
}
