#pragma once

#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/synth/renderer.h"

namespace sdoslam::synth {

// Rows rendered at one time under a rolling shutter (a 23 ms readout moves 0.4 ms a band).
inline constexpr int kRollingShutterBandRows = 8;

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
  // through each pixel centre (aliased edges, the default docs/results.md's figures use); 2 or more
  // average that many squared over each pixel, as a camera's photosites do.
  int supersampling = 1;
  // A rolling shutter: the rows are exposed one after another over this many seconds, top to
  // bottom, the middle row at the frame's time (its pose is the ground truth). 0: all at once.
  // Rendered in bands of kRollingShutterBandRows rows; not combined with motion blur or
  // supersampling.
  double readout_time = 0.0;

  void Check() const;
};

// Standard normal values from a std::mt19937, the same bit for bit as
// std::normal_distribution<float>(0, 1) draws them in libstdc++ (Marsaglia's polar method: two
// values a draw, the second kept for the next call). Written out because the library's call per
// value, which the compiler does not inline, was a quarter of the time to render a synthetic
// sequence, and the tests render thousands of frames; the same values keep every sequence, and
// every figure measured on one, as it was (test:
// Sensor.UnitNormalDrawsWhatTheStandardLibraryDraws).
class UnitNormal {
 public:
  explicit UnitNormal(std::mt19937& rng) : rng_(rng) {}
  float operator()() {
    if (saved_available_) {
      saved_available_ = false;
      return saved_;
    }
    const Pair p = DrawPair();
    const float mult = Multiplier(p.r2);
    saved_ = p.x * mult;
    saved_available_ = true;
    return p.y * mult;
  }

  // The next n values, as n calls would return them. The draws come first, then the roots and
  // logarithms: apart, the arithmetic of one pair no longer waits for a mispredicted rejection
  // of the next (a 60-frame synthetic sequence: 8 % less CPU).
  void Fill(float* out, size_t n) {
    size_t k = 0;
    if (n > 0 && saved_available_) {
      saved_available_ = false;
      out[k++] = saved_;
    }
    pairs_.resize((n - k + 1) / 2);
    for (Pair& p : pairs_) p = DrawPair();
    for (const Pair& p : pairs_) {
      const float mult = Multiplier(p.r2);
      out[k++] = p.y * mult;
      if (k == n) {
        saved_ = p.x * mult;
        saved_available_ = true;
        break;
      }
      out[k++] = p.x * mult;
    }
  }

 private:
  struct Pair {
    float x, y, r2;
  };
  // A point drawn uniformly in the unit disc (its centre excluded), as libstdc++ draws it.
  Pair DrawPair() {
    Pair p;
    do {
      // As libstdc++ writes it: 2 · u in float, minus 1.0 in double, rounded back to float.
      p.x = static_cast<float>(2.0f * Canonical() - 1.0);
      p.y = static_cast<float>(2.0f * Canonical() - 1.0);
      p.r2 = p.x * p.x + p.y * p.y;
    } while (p.r2 > 1.0f || p.r2 == 0.0f);
    return p;
  }
  static float Multiplier(float r2) { return std::sqrt(-2 * std::log(r2) / r2); }
  // std::generate_canonical<float, 24> over a 32-bit engine: one draw scaled by 2^-32, kept
  // below 1.
  float Canonical() {
    const float u = static_cast<float>(rng_()) / 4294967296.0f;
    return u >= 1.0f ? std::nextafter(1.0f, 0.0f) : u;
  }

  std::mt19937& rng_;
  float saved_ = 0;
  bool saved_available_ = false;
  std::vector<Pair> pairs_;  // Fill's draws, kept for the next call
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
