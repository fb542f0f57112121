// A YAML config as `run --config` reads it: the camera and dynamic sections, unknown and
// duplicate keys. (The SLAM sections use the same ConfigMap reads; they are left out so that
// the fuzz build stays small.)
#include "fuzz_util.h"
#include "sdoslam/core/camera.h"
#include "sdoslam/core/config.h"
#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/front_end.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = sdoslam::fuzz::WriteInput("config.yaml", sdoslam::fuzz::AsText(data, size));
  try {
    sdoslam::ConfigMap root = sdoslam::ConfigMap::LoadFile(path);
    std::string mode;
    root.Read("mode", &mode);
    if (auto camera = root.Section("camera")) sdoslam::ReadCameraOptions(*camera);
    sdoslam::ReadFrontEndOptions(root);
    for (const char* section : {"run", "orb", "rgbd", "tracking", "consistency", "mapping"}) {
      if (auto s = root.Section(section)) {
        for (const char* key : {"dataset", "max_frames", "features", "iterations"}) {
          std::string text;
          s->Read(key, &text);
        }
      }
    }
    root.RejectUnknownKeys();
  } catch (const sdoslam::Error&) {
  }
  return 0;
}
