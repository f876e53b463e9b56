// libFuzzer target: ReadScan on arbitrary bytes. The first byte picks the format (.pcd,
// .ply, .xyz) so one corpus covers all three readers. Anything but InputError is a finding.
#include "fuzz_common.hpp"
#include "furnihost/host/io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const char* const kExt[] = {".pcd", ".ply", ".xyz"};
  const std::string path =
      furnihost::fuzz::Write(std::string("scan") + kExt[data[0] % 3], reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    // The cap is what scan_file always passes (>= 1): a declared size above it must be
    // refused before anything is allocated.
    furnihost::ReadScan(path, nullptr, 100000);
  } catch (const furnihost::InputError&) {
  }
  return 0;
}
