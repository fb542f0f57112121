#include "sdoslam/map/frame.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace sdoslam {

FrameGeometry::FrameGeometry(const Camera& cam, const OrbExtractor& extractor, double bf_value,
                             double close_depth_value)
    : camera(cam),
      scale(extractor.scale()),
      inv_sigma2(extractor.inv_sigma2()),
      close_depth(close_depth_value) {
  const CameraOptions& o = camera.options();
  intrinsics = {o.fx, o.fy, o.cx, o.cy, bf_value};
  log_scale_factor = std::log(extractor.options().scale_factor);
  // With distortion, the undistorted image is not the rectangle [0,w)x[0,h): take the corners.
  const auto corners =
      camera.UndistortPoints({{0, 0},
                              {static_cast<float>(o.width), 0},
                              {0, static_cast<float>(o.height)},
                              {static_cast<float>(o.width), static_cast<float>(o.height)}});
  min_x = std::min(corners[0].x, corners[2].x);
  max_x = std::max(corners[1].x, corners[3].x);
  min_y = std::min(corners[0].y, corners[1].y);
  max_y = std::max(corners[2].y, corners[3].y);
  grid_cell_inv_w = kGridCols / (max_x - min_x);
  grid_cell_inv_h = kGridRows / (max_y - min_y);
}

cv::Mat GrayImage(const cv::Mat& image) {
  if (image.channels() != 3) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  return gray;
}

Frame::Frame(size_t frame_index, double time, const cv::Mat& bgr, const cv::Mat& depth_image,
             std::shared_ptr<const FrameGeometry> shared_geometry, const OrbExtractor& extractor,
             const cv::Mat& given_gray, const ExtractionAreas& areas)
    : index(frame_index), timestamp(time), geometry(std::move(shared_geometry)) {
  const cv::Mat gray = given_gray.empty() ? GrayImage(bgr) : given_gray;
  CV_Assert(gray.type() == CV_8UC1 && gray.size() == bgr.size());
  extractor.Extract(gray, &keypoints, &descriptors, areas);
  std::vector<cv::Point2f> points;
  points.reserve(keypoints.size());
  for (const auto& k : keypoints) points.push_back(k.pt);
  undistorted = geometry->camera.UndistortPoints(points);
  const size_t n = keypoints.size();
  depth.assign(n, 0.0f);
  right_u.assign(n, -1.0f);
  map_points.assign(n, nullptr);
  outlier.assign(n, false);
  label.assign(n, 0);
  colors.assign(n, cv::Vec3b(0, 0, 0));
  for (size_t i = 0; i < n; ++i) {
    const int u = static_cast<int>(std::lround(keypoints[i].pt.x)),
              v = static_cast<int>(std::lround(keypoints[i].pt.y));
    const int cu = std::clamp(u, 0, bgr.cols - 1), cv_row = std::clamp(v, 0, bgr.rows - 1);
    if (bgr.type() == CV_8UC3) {
      colors[i] = bgr.at<cv::Vec3b>(cv_row, cu);
    } else if (bgr.type() == CV_8UC1) {
      const uint8_t g = bgr.at<uint8_t>(cv_row, cu);
      colors[i] = cv::Vec3b(g, g, g);
    }
    if (!depth_image.empty() && u >= 0 && v >= 0 && u < depth_image.cols && v < depth_image.rows) {
      const float d = depth_image.at<float>(v, u);
      if (d > 0) {
        depth[i] = d;
        right_u[i] = static_cast<float>(undistorted[i].x - geometry->intrinsics.bf / d);
      }
    }
  }
  BuildGrid();
}

std::vector<uint8_t> Frame::ValuesAtKeypoints(const cv::Mat& image) const {
  CV_Assert(image.type() == CV_8UC1);
  std::vector<uint8_t> values(size());
  for (size_t i = 0; i < size(); ++i) {
    const int u = std::clamp(static_cast<int>(std::lround(keypoints[i].pt.x)), 0, image.cols - 1);
    const int v = std::clamp(static_cast<int>(std::lround(keypoints[i].pt.y)), 0, image.rows - 1);
    values[i] = image.at<uint8_t>(v, u);
  }
  return values;
}

void Frame::SetLabels(const cv::Mat& label_image) {
  if (label_image.empty()) {
    label.assign(size(), 0);
    return;
  }
  label = ValuesAtKeypoints(label_image);
  for (size_t i = 0; i < size(); ++i) {
    if (label[i] != 0) map_points[i] = nullptr;
  }
}

void Frame::SetUnmappable(const cv::Mat& mask) {
  unmappable_.clear();
  if (mask.empty()) return;
  unmappable_ = ValuesAtKeypoints(mask);
  for (uint8_t& u : unmappable_) u = u != 0;
}

void Frame::MarkDynamic(int i, uint8_t dynamic_label) {
  CV_Assert(dynamic_label != 0);
  const size_t k = static_cast<size_t>(i);
  label[k] = dynamic_label;  // FeaturesInArea skips it from now on
  map_points[k] = nullptr;
}

int Frame::GridCell(int i) const {
  const FrameGeometry& g = *geometry;
  const size_t k = static_cast<size_t>(i);
  const int gx = static_cast<int>((undistorted[k].x - g.min_x) * g.grid_cell_inv_w);
  const int gy = static_cast<int>((undistorted[k].y - g.min_y) * g.grid_cell_inv_h);
  if (gx < 0 || gy < 0 || gx >= FrameGeometry::kGridCols || gy >= FrameGeometry::kGridRows)
    return -1;
  return gy * FrameGeometry::kGridCols + gx;
}

void Frame::BuildGrid() {
  // Compressed rows (offsets + one index array): two allocations per frame instead of one per
  // cell, which matters because every keyframe keeps its grid.
  constexpr int kCells = FrameGeometry::kGridCols * FrameGeometry::kGridRows;
  grid_start_.assign(kCells + 1, 0);
  for (size_t i = 0; i < size(); ++i) {
    const int cell = GridCell(static_cast<int>(i));
    if (cell >= 0) ++grid_start_[static_cast<size_t>(cell) + 1];
  }
  for (int c = 0; c < kCells; ++c) grid_start_[c + 1] += grid_start_[c];
  grid_features_.assign(static_cast<size_t>(grid_start_.back()), 0);
  std::vector<int> next(grid_start_.begin(), grid_start_.end() - 1);
  for (size_t i = 0; i < size(); ++i) {
    const int cell = GridCell(static_cast<int>(i));
    if (cell >= 0)
      grid_features_[static_cast<size_t>(next[static_cast<size_t>(cell)]++)] = static_cast<int>(i);
  }
}

std::vector<int> Frame::FeaturesInArea(double u, double v, double radius, int min_level,
                                       int max_level) const {
  std::vector<int> result;
  if (grid_start_.empty()) return result;  // features released
  const FrameGeometry& g = *geometry;
  const int x0 =
      std::max(0, static_cast<int>(std::floor((u - g.min_x - radius) * g.grid_cell_inv_w)));
  const int x1 = std::min(FrameGeometry::kGridCols - 1,
                          static_cast<int>(std::ceil((u - g.min_x + radius) * g.grid_cell_inv_w)));
  const int y0 =
      std::max(0, static_cast<int>(std::floor((v - g.min_y - radius) * g.grid_cell_inv_h)));
  const int y1 = std::min(FrameGeometry::kGridRows - 1,
                          static_cast<int>(std::ceil((v - g.min_y + radius) * g.grid_cell_inv_h)));
  for (int gy = y0; gy <= y1; ++gy) {
    for (int gx = x0; gx <= x1; ++gx) {
      const size_t cell = static_cast<size_t>(gy * FrameGeometry::kGridCols + gx);
      for (int k = grid_start_[cell]; k < grid_start_[cell + 1]; ++k) {
        const int i = grid_features_[static_cast<size_t>(k)];
        if (label[static_cast<size_t>(i)] != 0) continue;  // dynamic: never matched
        const int level = keypoints[static_cast<size_t>(i)].octave;
        if ((min_level >= 0 && level < min_level) || (max_level >= 0 && level > max_level))
          continue;
        const double dx = undistorted[static_cast<size_t>(i)].x - u,
                     dy = undistorted[static_cast<size_t>(i)].y - v;
        if (std::abs(dx) < radius && std::abs(dy) < radius) result.push_back(i);
      }
    }
  }
  std::sort(result.begin(), result.end());
  return result;
}

Eigen::Isometry3d RowMotion::ToMiddleRow(double row, int height) const {
  const double s = (row - 0.5 * height) / height * readout_frames_;
  // M^s = [R^s | s t] to first order; its inverse is [R^-s | -R^-s s t].
  const Eigen::Matrix3d R_back =
      Eigen::AngleAxisd(-s * turn_.angle(), turn_.axis()).toRotationMatrix();
  Eigen::Isometry3d back = Eigen::Isometry3d::Identity();
  back.linear() = R_back;
  back.translation() = -R_back * (s * translation_);
  return back;
}

std::vector<cv::Point2f> UndistortToMiddleRow(const Camera& camera, const RowMotion& motion,
                                              const std::vector<cv::Point2f>& detected) {
  std::vector<cv::Point2f> undistorted = camera.UndistortPoints(detected);
  if (!motion.active()) return undistorted;
  for (size_t i = 0; i < undistorted.size(); ++i) {
    const Eigen::Vector3d ray = motion.ToMiddleRow(detected[i].y, camera.height()).linear() *
                                camera.Unproject({undistorted[i].x, undistorted[i].y}, 1.0);
    if (ray.z() <= 0) continue;
    const Eigen::Vector2d pixel = camera.Project(ray);
    undistorted[i] = cv::Point2f(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()));
  }
  return undistorted;
}

void Frame::CompensateRollingShutter(const RowMotion& motion) {
  row_motion = motion;
  if (!motion.active()) return;
  const Camera& camera = geometry->camera;
  for (size_t i = 0; i < size(); ++i) {
    // Without depth only the ray turns (such points are mostly beyond the sensor's range, where
    // a few millimetres of translation move nothing).
    const bool has_depth = depth[i] > 0;
    const Eigen::Isometry3d back = motion.ToMiddleRow(keypoints[i].pt.y, camera.height());
    const Eigen::Vector3d middle =
        has_depth ? Eigen::Vector3d(
                        back * camera.Unproject({undistorted[i].x, undistorted[i].y}, depth[i]))
                  : Eigen::Vector3d(back.linear() *
                                    camera.Unproject({undistorted[i].x, undistorted[i].y}, 1.0));
    if (middle.z() <= 0) continue;
    const Eigen::Vector2d pixel = camera.Project(middle);
    undistorted[i] = cv::Point2f(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()));
    if (has_depth) {
      depth[i] = static_cast<float>(middle.z());
      right_u[i] = static_cast<float>(undistorted[i].x - geometry->intrinsics.bf / depth[i]);
    }
  }
  BuildGrid();
}

Eigen::Vector3d Frame::UnprojectWorld(int i) const {
  const Eigen::Vector3d p = geometry->camera.Unproject(
      {undistorted[static_cast<size_t>(i)].x, undistorted[static_cast<size_t>(i)].y},
      depth[static_cast<size_t>(i)]);
  return T_camera_world.inverse() * p;
}

PointObservation Frame::Observation(int i) const {
  const size_t k = static_cast<size_t>(i);
  PointObservation m;
  m.pixel = Eigen::Vector2d(undistorted[k].x, undistorted[k].y);
  m.right_u = right_u[k];
  m.inv_sigma2 = geometry->inv_sigma2[static_cast<size_t>(keypoints[k].octave)];
  return m;
}

void Frame::ReleaseFeatures() {
  // Swapping with empty containers frees the memory; clear() would keep the capacity.
  std::vector<cv::KeyPoint>().swap(keypoints);
  std::vector<cv::Point2f>().swap(undistorted);
  std::vector<float>().swap(depth);
  std::vector<float>().swap(right_u);
  descriptors = cv::Mat(0, 32, CV_8U);
  std::vector<MapPoint*>().swap(map_points);
  std::vector<bool>().swap(outlier);
  std::vector<uint8_t>().swap(label);
  std::vector<uint8_t>().swap(unmappable_);
  std::vector<cv::Vec3b>().swap(colors);
  std::vector<int>().swap(grid_start_);  // FeaturesInArea finds nothing in a released frame
  std::vector<int>().swap(grid_features_);
}

}  // namespace sdoslam
