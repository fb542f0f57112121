#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

#include "sdoslam/core/camera.h"
#include "sdoslam/synth/renderer.h"

namespace sdoslam::synth {

// A Kinect-like RGB-D sensor applied to a perfect rendering.
struct SensorOptions {
  bool enabled = true;             // false: write the perfect rendering (quantised only)
  double image_noise_sigma = 2.0;  // Gaussian intensity noise, 8-bit units
  // Axial depth noise σ(z) = a + b·(z − 0.4)², metres (Nguyen et al. 2012 for the Kinect).
  double depth_noise_a = 0.0012;
  double depth_noise_b = 0.0019;
  // Systematic depth error growing towards the image corners, z · (1 + k·ρ²) with ρ the distance
  // from the image centre over the half diagonal: an uncalibrated Kinect's depth distortion
  // (Teichman et al. 2013; Herrera et al. 2012), which bends the map and makes loops drift.
  double depth_distortion = 0.0;
  // Depth is missing on the far side of a jump larger than this fraction of the depth
  // (the Kinect's shadow band at silhouettes).
  double silhouette_jump = 0.05;
  bool exposure_changes = false;     // slow random gain drift of the colour image
  double exposure_amplitude = 0.15;  // largest relative gain change
  int motion_blur_samples = 0;       // > 1: average this many renderings over the exposure
  double exposure_time = 0.015;      // seconds, for motion blur
  // Rays per pixel side for the colour image (synth/renderer.h, RenderColour): 1 renders one ray
  // through each pixel centre (aliased edges, the default the README's figures use); 2 or more
  // average that many squared over each pixel, as a camera's photosites do.
  int supersampling = 1;

  void Check() const;
};

struct SensorFrame {
  cv::Mat bgr;    // CV_8UC3
  cv::Mat depth;  // CV_16UC1, metres × camera.depth_factor; 0 = missing
};

// `gain` scales the colour (exposure); noise draws from a generator seeded by (seed, frame),
// so each frame is reproducible on its own.
SensorFrame Sense(const RenderedView& view, const CameraOptions& camera,
                  const SensorOptions& options, uint32_t seed, int frame, double gain = 1.0);

}  // namespace sdoslam::synth
