#include "sdoslam/tracking/scene_flow.h"

#include <algorithm>
#include <cmath>
#include <opencv2/video/tracking.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {

void SceneFlowOptions::Check(const std::string& path) const {
  if (frame_gap < 1) throw Error(path + "frame_gap must be >= 1");
  if (retry_gap < 0 || (retry_gap > 0 && retry_gap >= frame_gap))
    throw Error(path + "retry_gap must be 0 or in [1, frame_gap - 1]");
  if (!(min_flow >= 0)) throw Error(path + "min_flow must be >= 0");
  if (!(noise_sigmas > 0)) throw Error(path + "noise_sigmas must be positive");
  if (!(depth_noise_a >= 0) || !(depth_noise_b >= 0))
    throw Error(path + "depth_noise_a and " + path + "depth_noise_b must be >= 0");
  if (!(pixel_sigma >= 0)) throw Error(path + "pixel_sigma must be >= 0");
  if (!(segment_ratio > 0 && segment_ratio < 1))
    throw Error(path + "segment_ratio must be in (0, 1)");
  if (min_segment_features < 1) throw Error(path + "min_segment_features must be >= 1");
  if (max_iterations < 1) throw Error(path + "max_iterations must be >= 1");
  if (min_inliers_kept < 6) throw Error(path + "min_inliers_kept must be >= 6");
  if (!(min_established_kept >= 0 && min_established_kept <= 1))
    throw Error(path + "min_established_kept must be in [0, 1]");
  if (established_observations < 1) throw Error(path + "established_observations must be >= 1");
  // Any width: an even window is centred on the point as well (its samples lie half a pixel
  // off the point's grid, which the bilinear interpolation takes in its stride).
  if (track_window < 5) throw Error(path + "track_window must be >= 5");
  if (track_levels < 0 || track_levels > 6) throw Error(path + "track_levels must be in [0, 6]");
  if (track_iterations < 1) throw Error(path + "track_iterations must be >= 1");
  if (!(max_track_error > 0)) throw Error(path + "max_track_error must be positive");
  if (!(max_round_trip_px > 0)) throw Error(path + "max_round_trip_px must be positive");
  if (!(skip_round_trip_px >= 0)) throw Error(path + "skip_round_trip_px must be >= 0");
  if (cull_after < 1) throw Error(path + "cull_after must be >= 1");
  if (!(seen_through_max_share >= 0 && seen_through_max_share <= 1))
    throw Error(path + "seen_through_max_share must be in [0, 1]");
  if (depth_window_radius < 0 || depth_window_radius > 10)
    throw Error(path + "depth_window_radius must be in [0, 10]");
  if (!(max_segment_area > 0 && max_segment_area <= 1))
    throw Error(path + "max_segment_area must be in (0, 1]");
  static_motion.Check(path + "static_motion.");
}

std::vector<uint8_t> LargeSegments(const cv::Mat& segment_image, double max_fraction) {
  CV_Assert(segment_image.type() == CV_32S);
  std::vector<int> area;
  for (int y = 0; y < segment_image.rows; ++y) {
    const int* row = segment_image.ptr<int>(y);
    for (int x = 0; x < segment_image.cols; ++x) {
      if (row[x] < 0) continue;
      const auto s = static_cast<size_t>(row[x]);
      if (s >= area.size()) area.resize(s + 1, 0);
      ++area[s];
    }
  }
  std::vector<uint8_t> large(area.size(), 0);
  const double limit = max_fraction * static_cast<double>(segment_image.total());
  for (size_t s = 0; s < area.size(); ++s) large[s] = area[s] > limit;
  return large;
}

double DepthNoiseSigma(const SceneFlowOptions& o, double depth) {
  const double d = depth - 0.4;
  return o.depth_noise_a + o.depth_noise_b * d * d;
}

double AlongRayLimit(const SceneFlowOptions& o, double depth) {
  return o.min_flow + o.noise_sigmas * std::sqrt(2.0) * DepthNoiseSigma(o, depth);
}

bool ExceedsSceneFlowThreshold(const SceneFlowOptions& o, const Eigen::Vector3d& flow_world,
                               const Eigen::Vector3d& point_world,
                               const Eigen::Vector3d& camera_centre, double depth,
                               double focal_px) {
  const Eigen::Vector3d ray = (point_world - camera_centre).normalized();
  const double along = std::abs(flow_world.dot(ray));
  const double across = (flow_world - flow_world.dot(ray) * ray).norm();
  const double across_limit =
      o.min_flow + o.noise_sigmas * std::sqrt(2.0) * o.pixel_sigma * depth / focal_px;
  return along > AlongRayLimit(o, depth) || across > across_limit;
}

std::vector<uint8_t> ClassifyBySceneFlow(const SceneFlowOptions& o,
                                         const std::vector<uint8_t>& measured,
                                         const std::vector<uint8_t>& exceeds,
                                         const std::vector<int>& segment,
                                         const std::vector<uint8_t>& locked_segments,
                                         const std::vector<uint8_t>& large_segments,
                                         std::vector<uint8_t>* segment_dynamic_out) {
  const size_t n = measured.size();
  CV_Assert(exceeds.size() == n && segment.size() == n);
  int segments = static_cast<int>(locked_segments.size());
  for (int s : segment) segments = std::max(segments, s + 1);
  std::vector<int> measured_count(static_cast<size_t>(segments), 0);
  std::vector<int> exceeding_count(static_cast<size_t>(segments), 0);
  for (size_t i = 0; i < n; ++i) {
    if (segment[i] < 0 || !measured[i]) continue;
    ++measured_count[static_cast<size_t>(segment[i])];
    exceeding_count[static_cast<size_t>(segment[i])] += exceeds[i] != 0;
  }
  std::vector<uint8_t> segment_dynamic(static_cast<size_t>(segments), 0);
  for (size_t s = 0; s < segment_dynamic.size(); ++s) {
    const bool locked = s < locked_segments.size() && locked_segments[s] != 0;
    const bool large = s < large_segments.size() && large_segments[s] != 0;
    const bool by_count = !large && measured_count[s] >= o.min_segment_features &&
                          exceeding_count[s] > o.segment_ratio * measured_count[s];
    segment_dynamic[s] = locked || by_count;
  }
  std::vector<uint8_t> dynamic(n, 0);
  for (size_t i = 0; i < n; ++i) {
    dynamic[i] = (measured[i] && exceeds[i]) ||
                 (segment[i] >= 0 && segment_dynamic[static_cast<size_t>(segment[i])]);
  }
  if (segment_dynamic_out != nullptr) *segment_dynamic_out = std::move(segment_dynamic);
  return dynamic;
}

LkPyramid BuildLkPyramid(const SceneFlowOptions& o, const cv::Mat& gray) {
  CV_Assert(gray.type() == CV_8UC1);
  LkPyramid pyramid;
  // Derivatives with the border calcOpticalFlowPyrLK gives them itself (constant), and never
  // the caller's buffer for level 0: the pyramid outlives the frame's images.
  cv::buildOpticalFlowPyramid(gray, pyramid, cv::Size(o.track_window, o.track_window),
                              o.track_levels, /*withDerivatives=*/true, cv::BORDER_REFLECT_101,
                              cv::BORDER_CONSTANT, /*tryReuseInputImage=*/false);
  return pyramid;
}

cv::Mat LkPyramidImage(const LkPyramid& pyramid, int level) {
  // BuildLkPyramid keeps the derivatives: image and derivatives alternate.
  const size_t index = 2 * static_cast<size_t>(level);
  return level >= 0 && index < pyramid.size() ? pyramid[index] : cv::Mat();
}

void TrackPointsBack(const SceneFlowOptions& o, const cv::Mat& current_gray,
                     const cv::Mat& previous_gray, const std::vector<cv::Point2f>& points,
                     std::vector<cv::Point2f>* previous_points, std::vector<uint8_t>* found,
                     const std::vector<cv::Point2f>* guesses) {
  TrackPointsBack(o, BuildLkPyramid(o, current_gray), BuildLkPyramid(o, previous_gray), points,
                  previous_points, found, guesses);
}

void TrackPointsBack(const SceneFlowOptions& o, const LkPyramid& current, const LkPyramid& previous,
                     const std::vector<cv::Point2f>& points,
                     std::vector<cv::Point2f>* previous_points, std::vector<uint8_t>* found,
                     const std::vector<cv::Point2f>* guesses) {
  CV_Assert(!current.empty() && !previous.empty() && current[0].size() == previous[0].size());
  CV_Assert(guesses == nullptr || guesses->size() == points.size());
  const std::vector<cv::Point2f>& start = guesses != nullptr ? *guesses : points;
  previous_points->assign(start.begin(), start.end());
  found->assign(points.size(), 0);
  if (points.empty()) return;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(
      current, previous, points, *previous_points, *found, error,
      cv::Size(o.track_window, o.track_window), o.track_levels,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, o.track_iterations, 0.03),
      guesses != nullptr ? cv::OPTFLOW_USE_INITIAL_FLOW : 0);
  const float max_x = static_cast<float>(previous[0].cols - 1);
  const float max_y = static_cast<float>(previous[0].rows - 1);
  std::vector<size_t> kept;
  std::vector<cv::Point2f> starts;
  for (size_t i = 0; i < points.size(); ++i) {
    const cv::Point2f& p = (*previous_points)[i];
    if (!(error[i] <= o.max_track_error) || p.x < 0 || p.y < 0 || p.x > max_x || p.y > max_y) {
      (*found)[i] = 0;
    } else if ((*found)[i]) {
      const cv::Point2f off = guesses != nullptr ? p - (*guesses)[i] : cv::Point2f();
      const bool at_guess = guesses != nullptr && o.skip_round_trip_px > 0 &&
                            off.dot(off) <= o.skip_round_trip_px * o.skip_round_trip_px;
      if (!at_guess) {
        kept.push_back(i);
        starts.push_back(p);
      }
    }
  }
  if (kept.empty()) return;
  std::vector<cv::Point2f> returned;
  for (size_t i : kept) returned.push_back(points[i]);  // initial guess: where they started
  std::vector<uint8_t> returned_found;
  // No error output: the round trip is judged by where it ends, and without one OpenCV skips a
  // pass over each point's window.
  cv::calcOpticalFlowPyrLK(
      previous, current, starts, returned, returned_found, cv::noArray(),
      cv::Size(o.track_window, o.track_window), o.track_levels,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, o.track_iterations, 0.03),
      cv::OPTFLOW_USE_INITIAL_FLOW);
  for (size_t k = 0; k < kept.size(); ++k) {
    const cv::Point2f miss = returned[k] - points[kept[k]];
    if (!returned_found[k] || miss.dot(miss) > o.max_round_trip_px * o.max_round_trip_px)
      (*found)[kept[k]] = 0;
  }
}

std::vector<float> DepthCandidates(const cv::Mat& depth, cv::Point2f pixel, int radius) {
  CV_Assert(depth.type() == CV_32FC1);
  const int u = static_cast<int>(std::lround(pixel.x)), v = static_cast<int>(std::lround(pixel.y));
  std::vector<float> out;
  if (u < 0 || v < 0 || u >= depth.cols || v >= depth.rows) return out;
  float nearest = 0, farthest = 0;
  for (int y = std::max(0, v - radius); y <= std::min(depth.rows - 1, v + radius); ++y) {
    const float* row = depth.ptr<float>(y);
    for (int x = std::max(0, u - radius); x <= std::min(depth.cols - 1, u + radius); ++x) {
      if (!(row[x] > 0)) continue;
      if (nearest == 0 || row[x] < nearest) nearest = row[x];
      farthest = std::max(farthest, row[x]);
    }
  }
  if (nearest == 0) return out;
  const float centre = depth.at<float>(v, u);
  if (centre > 0) out.push_back(centre);
  for (float d : {nearest, farthest}) {
    if (std::find(out.begin(), out.end(), d) == out.end()) out.push_back(d);
  }
  return out;
}

std::vector<int> SegmentsAt(const cv::Mat& segment_image, cv::Size image_size,
                            const std::vector<cv::Point2f>& points) {
  std::vector<int> out(points.size(), -1);
  if (segment_image.empty()) return out;
  CV_Assert(segment_image.type() == CV_32SC1);
  const double sx = static_cast<double>(segment_image.cols) / image_size.width;
  const double sy = static_cast<double>(segment_image.rows) / image_size.height;
  for (size_t i = 0; i < points.size(); ++i) {
    const int x = std::clamp(static_cast<int>(points[i].x * sx), 0, segment_image.cols - 1);
    const int y = std::clamp(static_cast<int>(points[i].y * sy), 0, segment_image.rows - 1);
    out[i] = segment_image.at<int>(y, x);
  }
  return out;
}

}  // namespace sdoslam
