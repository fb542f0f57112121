#include "sdoslam/dynamic/detection_hold.h"

#include <algorithm>

#include "sdoslam/core/error.h"

namespace sdoslam {

void DetectionHoldOptions::Check(const std::string& path) const {
  if (hold_frames < 0) throw Error(path + "hold_frames must be at least 0");
  if (hold_min_hits < 1) throw Error(path + "hold_min_hits must be at least 1");
  if (!(hold_match_overlap > 0 && hold_match_overlap <= 1))
    throw Error(path + "hold_match_overlap must be in (0, 1]");
}

namespace {

bool SameClass(const Detection& a, const Detection& b) {
  return a.class_id >= 0 && b.class_id >= 0 ? a.class_id == b.class_id
                                            : a.class_name == b.class_name;
}

// The intersection's share of the smaller box.
double OverlapOfSmaller(const cv::Rect2f& a, const cv::Rect2f& b) {
  const double smaller = std::min(a.area(), b.area());
  return smaller > 0 ? (a & b).area() / smaller : 0.0;
}

}  // namespace

void DetectionHold::Observe(const std::vector<Detection>& fresh) {
  // Each fresh box continues the held box of its class it overlaps most (greedy, highest
  // overlap first), so one person keeps one box.
  struct Pair {
    double overlap;
    size_t fresh, held;
  };
  std::vector<Pair> pairs;
  for (size_t f = 0; f < fresh.size(); ++f) {
    for (size_t h = 0; h < boxes_.size(); ++h) {
      if (!SameClass(fresh[f], boxes_[h])) continue;
      const double overlap = OverlapOfSmaller(fresh[f].box, boxes_[h].box);
      if (overlap >= options_.hold_match_overlap) pairs.push_back({overlap, f, h});
    }
  }
  std::stable_sort(pairs.begin(), pairs.end(),
                   [](const Pair& a, const Pair& b) { return a.overlap > b.overlap; });
  std::vector<int> continues(fresh.size(), -1);
  std::vector<uint8_t> taken(boxes_.size(), 0);
  for (const Pair& p : pairs) {
    if (continues[p.fresh] >= 0 || taken[p.held]) continue;
    continues[p.fresh] = static_cast<int>(p.held);
    taken[p.held] = 1;
  }
  std::vector<Detection> boxes;
  std::vector<int> ages, hits;
  for (size_t f = 0; f < fresh.size(); ++f) {
    boxes.push_back(fresh[f]);
    boxes.back().held = false;
    ages.push_back(0);
    hits.push_back(continues[f] >= 0 ? hits_[static_cast<size_t>(continues[f])] + 1 : 1);
  }
  for (size_t h = 0; h < boxes_.size(); ++h) {
    if (taken[h] || hits_[h] < options_.hold_min_hits || ages_[h] + 1 > options_.hold_frames)
      continue;
    boxes.push_back(boxes_[h]);
    boxes.back().held = true;
    ages.push_back(ages_[h] + 1);
    hits.push_back(hits_[h]);
  }
  boxes_ = std::move(boxes);
  ages_ = std::move(ages);
  hits_ = std::move(hits);
  since_observe_ = 0;
}

void DetectionHold::Skip() {
  ++since_observe_;
  // The last detector frame's boxes stay until the next one; held boxes until hold_frames.
  std::vector<uint8_t> keep(boxes_.size(), 0);
  for (size_t b = 0; b < boxes_.size(); ++b) {
    ++ages_[b];
    keep[b] = ages_[b] <= options_.hold_frames || ages_[b] <= since_observe_;
  }
  Keep(keep);
}

void DetectionHold::Keep(const std::vector<uint8_t>& keep) {
  size_t kept = 0;
  for (size_t b = 0; b < boxes_.size(); ++b) {
    if (!keep[b]) continue;
    boxes_[kept] = boxes_[b];
    ages_[kept] = ages_[b];
    hits_[kept] = hits_[b];
    ++kept;
  }
  boxes_.resize(kept);
  ages_.resize(kept);
  hits_.resize(kept);
}

void DetectionHold::Follow(const std::vector<cv::Rect2f>& extents, double max_step) {
  CV_Assert(extents.size() == boxes_.size());
  std::vector<uint8_t> keep(boxes_.size(), 1);
  for (size_t b = 0; b < boxes_.size(); ++b) {
    cv::Rect2f& box = boxes_[b].box;
    const cv::Rect2f& e = extents[b];
    if (!boxes_[b].held) continue;  // the detector's own box stands
    if (e.area() <= 0) {
      keep[b] = 0;
      continue;
    }
    const auto clamp = [max_step](float now, float seen) {
      return std::clamp(seen, static_cast<float>(now / max_step),
                        static_cast<float>(now * max_step));
    };
    const float w = clamp(box.width, e.width), h = clamp(box.height, e.height);
    const cv::Point2f centre(e.x + e.width / 2, e.y + e.height / 2);
    box = cv::Rect2f(centre.x - w / 2, centre.y - h / 2, w, h);
  }
  Keep(keep);
}

}  // namespace sdoslam
