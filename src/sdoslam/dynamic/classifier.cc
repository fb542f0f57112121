#include "sdoslam/dynamic/classifier.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

struct SegmentStats {
  int area = 0;
  int outline = 0;  // outline pixels
  int outline_on_boundary = 0;
  int depth_pairs = 0;  // neighbour pairs across the outline with depth on both sides
  int in_front = 0;     // ... where this segment is the nearer side
  int behind = 0;       // ... where the other segment is the nearer side
  float median_depth = 0;
  std::vector<float> depths;
};

float Median(std::vector<float>* v) {
  if (v->empty()) return 0;
  auto mid = v->begin() + static_cast<std::ptrdiff_t>(v->size() / 2);
  std::nth_element(v->begin(), mid, v->end());
  return *mid;
}

// Whether a segment lies behind what borders it: the nearer side along less than `min_in_front`
// of its depth-ordered outline pairs, of which it has at least `min_ordered`.
bool LiesBehind(const SegmentStats& st, double min_in_front, int min_ordered) {
  const int ordered = st.in_front + st.behind;
  return ordered >= min_ordered && st.in_front < min_in_front * ordered;
}

}  // namespace

void SdoClassifierOptions::Check(const std::string& path) const {
  if (work_width < 16) throw Error(path + "work_width must be at least 16");
  auto fraction = [&path](double v, const char* name) {
    if (v < 0 || v > 1) throw Error(path + name + " must be in [0, 1]");
  };
  fraction(min_box_iou, "min_box_iou");
  fraction(min_inside_box, "min_inside_box");
  fraction(min_outline_on_boundary, "min_outline_on_boundary");
  fraction(min_in_front, "min_in_front");
  fraction(min_in_front_of_outline, "min_in_front_of_outline");
  fraction(max_segment_area, "max_segment_area");
  fraction(persistence_overlap, "persistence_overlap");
  fraction(persistence_large_overlap, "persistence_large_overlap");
  fraction(persistence_min_in_front, "persistence_min_in_front");
  fraction(known_min_in_front, "known_min_in_front");
  fraction(unmapped_min_outline_on_boundary, "unmapped_min_outline_on_boundary");
  if (unmapped_frames < 0 || unmapped_frames > 250)
    throw Error(path + "unmapped_frames must be in [0, 250]");
  if (persistence_min_ordered < 0) throw Error(path + "persistence_min_ordered must be ≥ 0");
  if (same_depth_tolerance < 0) throw Error(path + "same_depth_tolerance must be ≥ 0");
  if (same_depth_min_m < 0) throw Error(path + "same_depth_min_m must be ≥ 0");
  if (in_front_ratio < 1) throw Error(path + "in_front_ratio must be ≥ 1");
  if (boundary_band_px < 0 || margin_px < 0 || persistence_frames < 0 || persistence_frames > 250)
    throw Error(path + "boundary_band_px, " + path + "margin_px ≥ 0; " + path +
                "persistence_frames in [0, 250]");
}

SdoClassifier::SdoClassifier(const SdoClassifierOptions& options) : options_(options) {
  options_.Check();
}

namespace {

// Per segment: area, outline, the outline on a motion boundary (`near_boundary`), and the depth
// order across the outline (`depth`, at the segments' resolution).
std::vector<SegmentStats> MeasureSegments(const cv::Mat& seg, int n, const cv::Mat& depth,
                                          const cv::Mat& near_boundary, double in_front_ratio) {
  const cv::Size work = seg.size();
  std::vector<SegmentStats> stats(static_cast<size_t>(n));
  for (int y = 0; y < work.height; ++y) {
    const int* row = seg.ptr<int>(y);
    const float* d = depth.ptr<float>(y);
    for (int x = 0; x < work.width; ++x) {
      const int s = row[x];
      if (s < 0) continue;
      SegmentStats& st = stats[static_cast<size_t>(s)];
      ++st.area;
      if (d[x] > 0) st.depths.push_back(d[x]);
      bool outline = false;
      // Right and down neighbours: each pair is visited once and counts for both sides.
      const int nx[2] = {x + 1, x}, ny[2] = {y, y + 1};
      for (int k = 0; k < 2; ++k) {
        if (nx[k] >= work.width || ny[k] >= work.height) continue;
        const int t = seg.at<int>(ny[k], nx[k]);
        if (t == s) continue;
        outline = true;
        const float dt = depth.at<float>(ny[k], nx[k]);
        if (t >= 0 && d[x] > 0 && dt > 0) {
          SegmentStats& other = stats[static_cast<size_t>(t)];
          ++st.depth_pairs;
          ++other.depth_pairs;
          if (dt > d[x] * in_front_ratio) ++st.in_front, ++other.behind;
          if (d[x] > dt * in_front_ratio) ++other.in_front, ++st.behind;
        }
      }
      // Left and up neighbours only mark this pixel as outline.
      if (!outline && ((x > 0 && row[x - 1] != s) || (y > 0 && seg.at<int>(y - 1, x) != s)))
        outline = true;
      if (outline) {
        ++st.outline;
        st.outline_on_boundary += near_boundary.at<uint8_t>(y, x) != 0;
      }
    }
  }
  for (SegmentStats& st : stats) st.median_depth = Median(&st.depths);
  return stats;
}

// The pixels (255) of detection `det`'s object: the segment that best matches its box (`scale`:
// from image to segment resolution) and those mostly inside it at its depth, none of them lying
// behind its neighbours (known_min_in_front), labelled kKnownMovable in `segment_labels`; the
// whole box when no segment matches it; nothing when the best match lies behind. A held box
// (Detection::held) labels no bare box, and its best match is labelled whole, not clipped to
// the box, unless it is over kMaxHeldGrowth times the box: the box was placed by the flow
// frames ago, and a person walking up outgrows it, but a segment far larger than the box is
// more likely the room the box has slid onto.
constexpr double kMaxHeldGrowth = 2.0;

cv::Mat DetectedObject(const Detection& det, const cv::Mat& seg, int n,
                       const std::vector<SegmentStats>& stats, double scale,
                       const SdoClassifierOptions& options, std::vector<uint8_t>* segment_labels) {
  const cv::Size work = seg.size();
  cv::Mat member(work, CV_8U, cv::Scalar(0));
  const cv::Rect box = cv::Rect(cv::Point(static_cast<int>(std::floor(det.box.x * scale)),
                                          static_cast<int>(std::floor(det.box.y * scale))),
                                cv::Point(static_cast<int>(std::ceil(det.box.br().x * scale)),
                                          static_cast<int>(std::ceil(det.box.br().y * scale)))) &
                       cv::Rect(0, 0, work.width, work.height);
  if (box.area() <= 0) return member;
  std::vector<int> inside(static_cast<size_t>(n), 0);
  for (int y = box.y; y < box.br().y; ++y) {
    const int* row = seg.ptr<int>(y);
    for (int x = box.x; x < box.br().x; ++x) {
      if (row[x] >= 0) ++inside[static_cast<size_t>(row[x])];
    }
  }
  // The best match in front of its surroundings; and whether a match at least as good lies
  // behind them (then the box shows the background, and nothing is labelled).
  int best = -1;
  bool best_behind = false;
  double best_iou = options.min_box_iou, best_behind_iou = options.min_box_iou;
  std::vector<uint8_t> behind(static_cast<size_t>(n), 0);
  for (int s = 0; s < n; ++s) {
    const double in = inside[static_cast<size_t>(s)];
    if (in <= 0) continue;
    const SegmentStats& st = stats[static_cast<size_t>(s)];
    const double iou = in / (st.area + box.area() - in);
    behind[static_cast<size_t>(s)] =
        LiesBehind(st, options.known_min_in_front, options.persistence_min_ordered);
    if (behind[static_cast<size_t>(s)]) {
      if (iou >= best_behind_iou) best_behind_iou = iou, best_behind = true;
    } else if (iou >= best_iou) {
      best_iou = iou;
      best = s;
    }
  }
  if (best < 0) {
    if (!best_behind && !det.held) member(box).setTo(255);
    return member;
  }
  const bool whole_best =
      det.held && stats[static_cast<size_t>(best)].area <= kMaxHeldGrowth * box.area();
  const float best_depth = stats[static_cast<size_t>(best)].median_depth;
  std::vector<uint8_t> joins(static_cast<size_t>(n), 0);
  for (int s = 0; s < n; ++s) {
    const SegmentStats& st = stats[static_cast<size_t>(s)];
    const bool mostly_inside = inside[static_cast<size_t>(s)] >= options.min_inside_box * st.area;
    const bool same_depth =
        best_depth <= 0 || st.median_depth <= 0 ||
        std::abs(st.median_depth - best_depth) <=
            std::max(options.same_depth_tolerance * best_depth, options.same_depth_min_m);
    joins[static_cast<size_t>(s)] = s == best || (mostly_inside && same_depth && st.area > 0 &&
                                                  !behind[static_cast<size_t>(s)]);
    if (joins[static_cast<size_t>(s)]) (*segment_labels)[static_cast<size_t>(s)] = kKnownMovable;
  }
  for (int y = box.y; y < box.br().y; ++y) {
    const int* row = seg.ptr<int>(y);
    uint8_t* m = member.ptr<uint8_t>(y);
    for (int x = box.x; x < box.br().x; ++x) {
      if (row[x] >= 0 && joins[static_cast<size_t>(row[x])]) m[x] = 255;
    }
  }
  if (whole_best) member.setTo(255, seg == best);
  return member;
}

// Unknown objects selected by motion boundaries: per segment, 1 when its outline lies on them
// and it is the nearer side along its outline.
std::vector<uint8_t> SelectedByMotion(const std::vector<SegmentStats>& stats, int max_area,
                                      const SdoClassifierOptions& options) {
  std::vector<uint8_t> moving(stats.size(), 0);
  for (size_t s = 0; s < stats.size(); ++s) {
    const SegmentStats& st = stats[s];
    if (st.outline == 0 || st.area > max_area) continue;
    const bool on_boundary = st.outline_on_boundary >= options.min_outline_on_boundary * st.outline;
    const int ordered = st.in_front + st.behind;
    const bool in_front =
        st.depth_pairs == 0 || (st.in_front >= options.min_in_front * ordered &&
                                st.in_front >= options.min_in_front_of_outline * st.depth_pairs);
    moving[s] = on_boundary && in_front;
  }
  return moving;
}

// Where each pixel of a `work`-sized image was on the frame before, by `flow` (backward
// lookup, first order): the map cv::remap takes. Empty without flow. Built once a frame for the
// two memories the classifier carries (persistence, and the regions seen moving lately).
cv::Mat BackwardMap(const cv::Mat& flow, cv::Size work) {
  if (flow.empty()) return {};
  cv::Mat flow_work;
  cv::resize(flow, flow_work, work, 0, 0, cv::INTER_LINEAR);
  flow_work *= static_cast<double>(work.width) / flow.cols;
  cv::Mat map(work, CV_32FC2);
  for (int y = 0; y < work.height; ++y) {
    const cv::Vec2f* f = flow_work.ptr<cv::Vec2f>(y);
    cv::Vec2f* m = map.ptr<cv::Vec2f>(y);
    for (int x = 0; x < work.width; ++x)
      m[x] = cv::Vec2f(static_cast<float>(x) - f[x][0], static_cast<float>(y) - f[x][1]);
  }
  return map;
}

// A memory carried to this frame by `backward_map` (BackwardMap; empty: it stays in place).
cv::Mat CarryAlongFlow(const cv::Mat& memory, const cv::Mat& backward_map) {
  if (backward_map.empty()) return memory.clone();
  cv::Mat carried(memory.size(), CV_8U, cv::Scalar(0));
  cv::remap(memory, carried, backward_map, cv::noArray(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  return carried;
}

// Segments the carried `memory` covers stay dynamic (`moving` |= 2: remembered, not refreshed).
void MarkRemembered(const cv::Mat& memory, const cv::Mat& seg,
                    const std::vector<SegmentStats>& stats, int max_area,
                    const SdoClassifierOptions& options, std::vector<uint8_t>* moving) {
  std::vector<int> remembered(stats.size(), 0);
  for (int y = 0; y < seg.rows; ++y) {
    const int* row = seg.ptr<int>(y);
    const uint8_t* m = memory.ptr<uint8_t>(y);
    for (int x = 0; x < seg.cols; ++x) {
      if (row[x] >= 0 && m[x] > 0) ++remembered[static_cast<size_t>(row[x])];
    }
  }
  for (size_t s = 0; s < stats.size(); ++s) {
    const SegmentStats& st = stats[s];
    // The memory stays on the pixels a mover covered; where it has gone, the wall that comes
    // back into view there lies behind whatever borders it, and is not remembered.
    const bool behind =
        LiesBehind(st, options.persistence_min_in_front, options.persistence_min_ordered);
    const bool covered = st.area <= max_area
                             ? remembered[s] >= options.persistence_overlap * st.area
                             : remembered[s] >= options.persistence_large_overlap * st.area;
    if (st.area > 0 && !behind && covered) (*moving)[s] |= 2;
  }
}

// The boundary mask at work resolution (`work_mask`, 0/255; all 0 without a mask) and the band
// of `band_px` around it in which a segment's outline counts as on a boundary.
cv::Mat BoundaryBand(const cv::Mat& boundary_mask, cv::Size work, int band_px, cv::Mat* work_mask) {
  cv::Mat band(work, CV_8U, cv::Scalar(0));
  if (boundary_mask.empty()) {
    *work_mask = cv::Mat(work, CV_8U, cv::Scalar(0));
    return band;
  }
  cv::resize(boundary_mask, *work_mask, work, 0, 0, cv::INTER_AREA);
  cv::threshold(*work_mask, *work_mask, 0, 255, cv::THRESH_BINARY);
  cv::dilate(*work_mask, band,
             cv::getStructuringElement(cv::MORPH_RECT, {2 * band_px + 1, 2 * band_px + 1}));
  return band;
}

// Per segment, whether it was seen moving: freshly selected by motion (`moving` & 1; with
// first_selection_is_tentative, also remembered from an earlier selection: `moving` 3) with at
// least unmapped_min_outline_on_boundary of its outline on boundaries. Empty when
// unmapped_frames is 0 (nothing is kept unmapped).
std::vector<uint8_t> SeenMoving(const std::vector<SegmentStats>& stats,
                                const std::vector<uint8_t>& moving,
                                const SdoClassifierOptions& options) {
  std::vector<uint8_t> seen;
  if (options.unmapped_frames == 0) return seen;
  seen.resize(stats.size());
  for (size_t s = 0; s < stats.size(); ++s) {
    const bool selected = options.first_selection_is_tentative ? moving[s] == 3 : (moving[s] & 1);
    seen[s] = selected && stats[s].outline_on_boundary >=
                              options.unmapped_min_outline_on_boundary * stats[s].outline;
  }
  return seen;
}

// `work_labels` (grown by margin_px) with the pixels of the segments selected by motion for the
// first time (`moving` 1: fresh, not remembered) static, and the ring grown around them kept;
// empty when there are none.
cv::Mat WithoutFirstSelections(const cv::Mat& seg, const std::vector<uint8_t>& moving,
                               const cv::Mat& work_labels) {
  if (std::find(moving.begin(), moving.end(), 1) == moving.end()) return {};
  cv::Mat kept = work_labels.clone();
  for (int y = 0; y < seg.rows; ++y) {
    const int* row = seg.ptr<int>(y);
    uint8_t* out = kept.ptr<uint8_t>(y);
    for (int x = 0; x < seg.cols; ++x) {
      if (out[x] == kMovingUnknown && moving[static_cast<size_t>(row[x])] == 1) out[x] = kStatic;
    }
  }
  return kept;
}

}  // namespace

SdoResult SdoClassifier::Classify(const Segmentation& segments,
                                  const std::vector<Detection>& detections,
                                  const cv::Mat& boundary_mask, const cv::Mat& flow,
                                  const cv::Mat& depth, cv::Size image_size) {
  const double scale = static_cast<double>(options_.work_width) / image_size.width;
  const cv::Size work(options_.work_width,
                      std::max(1, static_cast<int>(std::lround(image_size.height * scale))));
  SdoResult result;
  result.detections = detections;
  result.segments.count = segments.count;
  if (segments.labels.size() == work) {
    result.segments.labels = segments.labels;
  } else {
    cv::resize(segments.labels, result.segments.labels, work, 0, 0, cv::INTER_NEAREST);
  }
  const cv::Mat& seg = result.segments.labels;
  const int n = segments.count;
  cv::Mat depth_work(work, CV_32F, cv::Scalar(0));
  if (!depth.empty()) cv::resize(depth, depth_work, work, 0, 0, cv::INTER_NEAREST);
  const cv::Mat near_boundary =
      BoundaryBand(boundary_mask, work, options_.boundary_band_px, &result.boundary_mask);
  const std::vector<SegmentStats> stats =
      MeasureSegments(seg, n, depth_work, near_boundary, options_.in_front_ratio);

  // Known movable classes.
  result.segment_labels.assign(static_cast<size_t>(n), kStatic);
  cv::Mat known(work, CV_8U, cv::Scalar(0));
  const auto& movable = options_.movable_classes;
  result.detection_extents.assign(detections.size(), cv::Rect2f());
  for (size_t d = 0; d < detections.size(); ++d) {
    const Detection& det = detections[d];
    if (std::find(movable.begin(), movable.end(), det.class_name) == movable.end()) continue;
    const cv::Mat member =
        DetectedObject(det, seg, n, stats, scale, options_, &result.segment_labels);
    const cv::Rect extent = cv::boundingRect(member);
    if (extent.area() > 0) {
      result.detection_extents[d] = cv::Rect2f(
          static_cast<float>(extent.x / scale), static_cast<float>(extent.y / scale),
          static_cast<float>(extent.width / scale), static_cast<float>(extent.height / scale));
    }
    known |= member;
  }
  // Unknown objects: selected by motion boundaries, or remembered from the frames before.
  const int max_area = static_cast<int>(options_.max_segment_area * work.area());
  std::vector<uint8_t> moving = SelectedByMotion(stats, max_area, options_);
  const bool carries_recent =
      options_.unmapped_frames > 0 && !recently_moving_.empty() && recently_moving_.size() == work;
  const bool carries_memory = !memory_.empty() && memory_.size() == work;
  const cv::Mat backward_map =
      carries_memory || carries_recent ? BackwardMap(flow, work) : cv::Mat();
  cv::Mat memory(work, CV_8U, cv::Scalar(0));
  if (carries_memory) {
    memory = CarryAlongFlow(memory_, backward_map);
    MarkRemembered(memory, seg, stats, max_area, options_, &moving);
    cv::subtract(memory, cv::Scalar(1), memory);  // saturates at 0
  }
  for (int s = 0; s < n; ++s) {
    if (moving[static_cast<size_t>(s)] && result.segment_labels[static_cast<size_t>(s)] == kStatic)
      result.segment_labels[static_cast<size_t>(s)] = kMovingUnknown;
  }
  PaintLabels(seg, known, moving, &memory, &result);
  memory_ = memory;
  const cv::Mat recently_moving =
      RecentlyMoving(seg, known, SeenMoving(stats, moving, options_), backward_map);
  // Grows dynamic regions by margin_px (max filter: known-movable wins over moving-unknown only
  // by value order, which is fine: both are dynamic).
  auto grow = [r = options_.margin_px](cv::Mat* labels) {
    if (r <= 0 || labels->empty()) return;
    cv::Mat grown;
    cv::dilate(*labels, grown, cv::getStructuringElement(cv::MORPH_RECT, {2 * r + 1, 2 * r + 1}));
    *labels = grown;
  };
  grow(&result.work_labels);
  cv::Mat budget_work;  // empty: the budget's labels are the labels
  if (options_.first_selection_is_tentative)
    budget_work = WithoutFirstSelections(seg, moving, result.work_labels);
  cv::resize(result.work_labels, result.labels, image_size, 0, 0, cv::INTER_NEAREST);
  if (budget_work.empty()) {
    result.budget_labels = result.labels;
  } else {
    cv::resize(budget_work, result.budget_labels, image_size, 0, 0, cv::INTER_NEAREST);
  }
  if (!recently_moving.empty()) {
    const cv::Mat unmapped = (recently_moving > 0) & (result.work_labels == kStatic);
    cv::resize(unmapped, result.unmapped, image_size, 0, 0, cv::INTER_NEAREST);
  }
  return result;
}

cv::Mat SdoClassifier::RecentlyMoving(const cv::Mat& seg, const cv::Mat& known,
                                      const std::vector<uint8_t>& seen_moving,
                                      const cv::Mat& backward_map) {
  if (options_.unmapped_frames == 0) return {};
  cv::Mat recent(seg.size(), CV_8U, cv::Scalar(0));
  if (!recently_moving_.empty() && recently_moving_.size() == seg.size()) {
    recent = CarryAlongFlow(recently_moving_, backward_map);
    cv::subtract(recent, cv::Scalar(1), recent);  // saturates at 0
  }
  const uint8_t refresh = static_cast<uint8_t>(options_.unmapped_frames);
  for (int y = 0; y < seg.rows; ++y) {
    const int* row = seg.ptr<int>(y);
    const uint8_t* k = known.ptr<uint8_t>(y);
    uint8_t* r = recent.ptr<uint8_t>(y);
    for (int x = 0; x < seg.cols; ++x) {
      if (k[x] || (row[x] >= 0 && seen_moving[static_cast<size_t>(row[x])])) r[x] = refresh;
    }
  }
  recently_moving_ = recent;
  return recent;
}

void SdoClassifier::PaintLabels(const cv::Mat& seg, const cv::Mat& known,
                                const std::vector<uint8_t>& moving, cv::Mat* memory,
                                SdoResult* result) const {
  // The label image; freshly selected segments refresh the memory.
  result->work_labels.create(seg.size(), CV_8U);
  const uint8_t refresh = static_cast<uint8_t>(options_.persistence_frames);
  for (int y = 0; y < seg.rows; ++y) {
    const int* row = seg.ptr<int>(y);
    const uint8_t* k = known.ptr<uint8_t>(y);
    uint8_t* out = result->work_labels.ptr<uint8_t>(y);
    uint8_t* m = memory->ptr<uint8_t>(y);
    for (int x = 0; x < seg.cols; ++x) {
      const int s = row[x];
      if (k[x]) {
        out[x] = kKnownMovable;
      } else if (s >= 0 && result->segment_labels[static_cast<size_t>(s)] == kMovingUnknown) {
        out[x] = kMovingUnknown;
      } else {
        out[x] = kStatic;
      }
      if (s >= 0 && (moving[static_cast<size_t>(s)] & 1)) m[x] = std::max(m[x], refresh);
    }
  }
}

}  // namespace sdoslam
