// manifest.json of a result set, as eval and eval-masks check it.
#include "fuzz_util.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/result_set.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace sdoslam::fuzz;
  WriteInput("set/manifest.json", AsText(data, size));
  WriteInput("set/frames.csv", "index\n");
  try {
    sdoslam::VerifyResultSet(ScratchDir() / "set");
  } catch (const sdoslam::Error&) {
  }
  return 0;
}
