#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "sdoslam/dynamic/segmenter.h"

namespace cv::rgbd {
class RgbdNormals;
}

namespace sdoslam {

// Segments that follow the geometry of the depth image (issue 15 part 2), after the geometric
// segmentation used for unknown objects in dense RGB-D SLAM (Tateno et al. 2015; Co-Fusion):
// a pixel is an edge where the depth steps (an occluding outline) or where the surface folds
// concavely (an object standing on a desk, a box on the floor); segments are the connected
// regions between edges. Edge and hole pixels then join the neighbouring segment of nearest
// depth, or of nearest colour where there is no depth, so outlines stay on the object they
// belong to. Concave creases cut, convex ones do not: a box's own edges are convex and keep it
// whole, while the line where it meets the floor is concave and cuts it off.
// Normals come from OpenCV's rgbd module (RgbdNormals, FALS); the edge test and the region
// growing are a few loops of our own, since no library here segments by concavity.
struct GeometricSegmenterOptions {
  // px; segmentation runs at this width (aspect kept). Not 240: that was cheaper and better on
  // the boxes of the real-background plays, but merged a walking-up person's head and torso into
  // one segment that the motion-boundary test no longer selected, and sdo followed the person.
  int work_width = 320;
  double depth_step = 0.04;            // an edge where neighbours' depths differ by this fraction
  double depth_step_min_m = 0.01;      // ... and by at least this many metres (sensor noise)
  double concave_angle_deg = 25;       // an edge where the surface folds concavely by this much
  int normal_window = 5;               // RgbdNormals window (1, 3, 5 or 7 work px)
  int concave_span_px = 3;             // the crease test looks this far to each side
  int min_size = 30;                   // px at work resolution; smaller regions join a neighbour
  int grow_passes = 6;                 // passes that give edge and hole pixels a segment
  double max_grow_depth_ratio = 0.15;  // an edge pixel joins only a segment this near in depth
  void Check(const std::string& path =
                 "dynamic.segmenter.geometric.") const;  // Error names path + setting

  // Calls visit(key, member) for every setting: one list of config keys for reading and writing.
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("work_width", o.work_width);
    visit("depth_step", o.depth_step);
    visit("depth_step_min_m", o.depth_step_min_m);
    visit("concave_angle_deg", o.concave_angle_deg);
    visit("normal_window", o.normal_window);
    visit("concave_span_px", o.concave_span_px);
    visit("min_size", o.min_size);
    visit("grow_passes", o.grow_passes);
    visit("max_grow_depth_ratio", o.max_grow_depth_ratio);
  }
};

class GeometricSegmenter : public Segmenter {
 public:
  // K: the camera matrix at full image resolution (normals need the back-projection).
  GeometricSegmenter(const GeometricSegmenterOptions& options, const cv::Matx33d& K,
                     cv::Size image_size);
  Segmentation Segment(const FrontEndFrame& frame) override;  // at work resolution

  // The edge map of the last frame at work resolution (CV_8U: 127 = depth step, 254 = concave
  // crease, 0 = none), for tests and overlays.
  const cv::Mat& last_edges() const { return last_edges_; }

 private:
  // The steps of Segment, on the work images. Marks depth steps between neighbours (a row, a
  // column and both diagonals) in last_edges_.
  void MarkDepthSteps();
  // Turns each normal towards the camera; makes those of pixels without depth or a finite
  // normal NaN (unusable).
  void OrientNormals();
  // Marks concave creases in last_edges_, and the region pixels (depth and no edge) in inside_.
  void MarkCreases();
  // The regions (connected region pixels, the small ones dissolved) into `labels_image`, -1
  // elsewhere; returns how many. The unlabelled pixels become candidates_ for growth.
  int LabelRegions(cv::Mat* labels_image);
  // Grows the regions into the unlabelled pixels (grow_passes passes).
  void GrowRegions(int* labels);

  GeometricSegmenterOptions options_;
  cv::Size work_size_;
  cv::Matx33d K_work_;  // the camera matrix at work resolution
  cv::Ptr<cv::rgbd::RgbdNormals> normals_;
  cv::Mat last_edges_;
  // Per-frame work buffers, kept so that their memory is reused from frame to frame.
  cv::Mat z_, bgr_, points_, normals_out_, inside_;
  cv::Mat components_, stats_, centroids_;
  std::vector<cv::Vec3f> colour_;  // L*a*b*, where has_colour_
  std::vector<uint8_t> has_colour_;
  std::vector<int> candidates_;             // pixels the next growth pass looks at
  std::vector<int> visited_;                // the pass that last made the pixel a candidate
  std::vector<std::pair<int, int>> grown_;  // (pixel, label) one growth pass gives
};

}  // namespace sdoslam
