#include "sdoslam/io/tum_dataset.h"

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/core/text_file.h"
#include "sdoslam/core/timestamps.h"
#include "sdoslam/io/dataset.h"

namespace sdoslam {
namespace {

struct ListEntry {
  double timestamp;
  std::string file;
};

// Reads rgb.txt / depth.txt: `timestamp filename` per line, timestamps strictly increasing.
std::vector<ListEntry> ReadFileList(const std::filesystem::path& path) {
  std::vector<ListEntry> list;
  ForEachDataLine(path, [&](int line, const std::vector<std::string>& tokens) {
    if (tokens.size() != 2) {
      throw Error(Where(path, line) + "expected 'timestamp filename', found " +
                  std::to_string(tokens.size()) + " columns");
    }
    const double t = ParseTimestamp(tokens[0], path, line, "timestamp");
    if (!list.empty() && t <= list.back().timestamp) {
      throw Error(Where(path, line) + "timestamp " + tokens[0] +
                  " does not increase over the line before");
    }
    list.push_back({t, tokens[1]});
  });
  return list;
}

std::string Range(const std::vector<ListEntry>& list) {
  if (list.empty()) return "(empty)";
  char buffer[96];
  std::snprintf(buffer, sizeof(buffer), "[%.6f, %.6f]", list.front().timestamp,
                list.back().timestamp);
  return buffer;
}

}  // namespace

void TumDatasetOptions::Check() const {
  if (!(max_time_difference > 0) || !std::isfinite(max_time_difference)) {
    throw Error("dataset.max_time_difference must be positive");
  }
}

TumDataset::TumDataset(const std::filesystem::path& folder, const CameraOptions& camera,
                       const TumDatasetOptions& options)
    : folder_(folder), camera_(camera) {
  options.Check();
  camera.Check();
  if (!std::filesystem::is_directory(folder))
    throw Error("dataset folder not found: " + folder.string());

  if (!options.associations.empty()) {
    const auto path =
        options.associations.is_absolute() ? options.associations : folder / options.associations;
    ForEachDataLine(path, [&](int line, const std::vector<std::string>& tokens) {
      if (tokens.size() != 4) {
        throw Error(Where(path, line) + "expected 't_rgb rgb_file t_depth depth_file', found " +
                    std::to_string(tokens.size()) + " columns");
      }
      RgbdFrameEntry entry;
      entry.timestamp = ParseTimestamp(tokens[0], path, line, "rgb timestamp");
      entry.depth_timestamp = ParseTimestamp(tokens[2], path, line, "depth timestamp");
      entry.rgb_path = folder / tokens[1];
      entry.depth_path = folder / tokens[3];
      if (!entries_.empty() && entry.timestamp <= entries_.back().timestamp) {
        throw Error(Where(path, line) + "timestamp " + tokens[0] +
                    " does not increase over the line before");
      }
      entries_.push_back(entry);
    });
    if (entries_.empty()) throw Error(path.string() + ": no frames listed");
  } else {
    const auto rgb_list = ReadFileList(folder / "rgb.txt");
    const auto depth_list = ReadFileList(folder / "depth.txt");
    if (rgb_list.empty()) throw Error((folder / "rgb.txt").string() + ": no frames listed");
    if (depth_list.empty()) throw Error((folder / "depth.txt").string() + ": no frames listed");
    std::vector<double> rgb_times, depth_times;
    for (const auto& e : rgb_list) rgb_times.push_back(e.timestamp);
    for (const auto& e : depth_list) depth_times.push_back(e.timestamp);
    for (const auto& [i, j] :
         AssociateTimestamps(rgb_times, depth_times, options.max_time_difference)) {
      entries_.push_back({rgb_list[i].timestamp, depth_list[j].timestamp, folder / rgb_list[i].file,
                          folder / depth_list[j].file});
    }
    if (entries_.empty()) {
      throw Error(folder.string() + ": no rgb/depth pair within " +
                  std::to_string(options.max_time_difference) + " s (rgb.txt spans " +
                  Range(rgb_list) + ", depth.txt spans " + Range(depth_list) + ")");
    }
  }

  for (const RgbdFrameEntry& entry : entries_) {
    for (const auto* path : {&entry.rgb_path, &entry.depth_path}) {
      if (!std::filesystem::exists(*path)) throw Error("listed image not found: " + path->string());
      RejectNonRegularFile(*path);
    }
  }
}

RgbdFrame TumDataset::Load(size_t index) const {
  if (index >= entries_.size()) {
    throw Error("frame " + std::to_string(index) + " out of range (" +
                std::to_string(entries_.size()) + " frames)");
  }
  return LoadRgbdFrame(entries_[index], index, camera_);
}

}  // namespace sdoslam
