#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <opencv2/core.hpp>
#include <ostream>
#include <string>
#include <vector>

namespace sdoslam {

// Confusion counts of a binary "dynamic" decision.
struct MaskCounts {
  uint64_t true_positive = 0, false_positive = 0, false_negative = 0, true_negative = 0;
  double Precision() const;  // 1 when nothing was predicted dynamic
  double Recall() const;     // 1 when nothing is dynamic
  double Iou() const;        // 1 when both are empty
  MaskCounts& operator+=(const MaskCounts& o);
};

struct MaskEvaluation {
  size_t frames = 0;
  MaskCounts pixels;    // every pixel of every frame
  MaskCounts features;  // every feature of every frame, judged at its pixel
  // Per object class ("person", ..., "unknown" for objects of no known class): pixels of that
  // class's moving objects, and predicted pixels within their bounding boxes (grown by 10 %)
  // that are not moving; predictions elsewhere count in `pixels` only.
  std::map<std::string, MaskCounts> per_class;
  // The same per class and frame, for each frame in which the class has moving pixels: a
  // summed IoU hides the frames where an object is missed altogether (a person standing still
  // that no detector sees), and "every frame the person is in view" is what a user needs.
  struct FrameScore {
    size_t frame;  // 0-based, in the order AddFrame was called
    std::string file;
    std::string class_name;
    MaskCounts counts;
  };
  std::vector<FrameScore> per_frame;
};

// Compares predicted dynamic masks with the ground truth of a synthetic sequence
// (`dynamic/` 255 = moving now, `instance/` ids, objects.json for their classes).
class MaskEvaluator {
 public:
  // Throws Error when the sequence has no dynamic/ or instance/ folder or no objects.json.
  explicit MaskEvaluator(const std::filesystem::path& sequence);
  // predicted: CV_8U at image size, non-zero = dynamic. features: positions with their
  // predicted labels (non-zero = dynamic); may be empty. Throws for a size mismatch.
  void AddFrame(const std::filesystem::path& rgb_path, const cv::Mat& predicted,
                const std::vector<cv::Point2f>& features = {},
                const std::vector<uint8_t>& feature_labels = {});
  const MaskEvaluation& result() const { return result_; }

 private:
  std::filesystem::path sequence_;
  // Class slot of each instance id (ids missing here and ids past the end: `unknown_slot_`),
  // so the per-pixel loop indexes arrays instead of looking names up.
  std::vector<int> slot_of_instance_;
  std::vector<std::string> class_names_;
  int unknown_slot_ = 0;
  MaskEvaluation result_;
};

// The summary `eval-masks` prints: overall, features, and per class its summed scores with the
// median and lowest IoU over the frames it is in view.
std::string FormatMaskEvaluation(const MaskEvaluation& e, const std::string& label);
// The header of WritePerFrameScores' CSV.
inline constexpr const char* kPerFrameScoresHeader =
    "run,frame,file,class,iou,true_positive,false_positive,false_negative";
// `e.per_frame` as CSV rows under kPerFrameScoresHeader, `run` naming the run in each.
void WritePerFrameScores(const MaskEvaluation& e, const std::string& run, std::ostream& out);

}  // namespace sdoslam
