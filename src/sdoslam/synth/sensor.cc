#include "sdoslam/synth/sensor.h"

#include <cmath>
#include <random>

#include "sdoslam/core/error.h"

namespace sdoslam::synth {

void SensorOptions::Check() const {
  auto require = [](bool ok, const char* field) {
    if (!ok) throw Error(std::string("sensor.") + field + " is out of range");
  };
  require(image_noise_sigma >= 0 && image_noise_sigma < 100, "image_noise_sigma");
  require(depth_noise_a >= 0 && depth_noise_b >= 0, "depth_noise_a/b");
  require(depth_distortion > -0.5 && depth_distortion < 0.5, "depth_distortion");
  require(silhouette_jump > 0, "silhouette_jump");
  require(exposure_amplitude >= 0 && exposure_amplitude < 1, "exposure_amplitude");
  require(motion_blur_samples >= 0 && motion_blur_samples <= 64, "motion_blur_samples");
  require(exposure_time >= 0 && exposure_time < 1, "exposure_time");
  require(supersampling >= 1 && supersampling <= 8, "supersampling");
  require(readout_time >= 0 && readout_time < 1, "readout_time");
  if (readout_time > 0 && (motion_blur_samples > 1 || supersampling > 1))
    throw Error("a rolling shutter (readout) does not combine with motion blur or supersampling");
}

SensorFrame Sense(const RenderedView& view, const CameraOptions& camera,
                  const SensorOptions& options, uint32_t seed, int frame, double gain) {
  const int w = view.depth.cols, h = view.depth.rows;
  std::mt19937 rng(seed * 7919u + static_cast<uint32_t>(frame) * 104729u + 17u);
  UnitNormal unit_normal(rng);
  const bool noisy = options.enabled;
  const auto out_of_range = [&camera](double z) {
    return z <= 0 || z < camera.depth_min || z > camera.depth_max;
  };

  SensorFrame out;
  out.bgr.create(h, w, CV_8UC3);
  std::vector<float> noise(static_cast<size_t>(3 * w));  // a row's values, drawn at once
  for (int v = 0; v < h; ++v) {
    const auto* in = view.colour.ptr<cv::Vec3f>(v);
    auto* px = out.bgr.ptr<cv::Vec3b>(v);
    if (noisy) unit_normal.Fill(noise.data(), noise.size());
    for (int u = 0; u < w; ++u) {
      for (int c = 0; c < 3; ++c) {
        float value = in[u][c] * 255.0f * static_cast<float>(gain);
        if (noisy) value += static_cast<float>(options.image_noise_sigma) * noise[3 * u + c];
        px[u][c] = cv::saturate_cast<uint8_t>(value);
      }
    }
  }

  out.depth.create(h, w, CV_16UC1);
  for (int v = 0; v < h; ++v) {
    const float* z_row = view.depth.ptr<float>(v);
    auto* d = out.depth.ptr<uint16_t>(v);
    // A value is drawn for each pixel in range (the shadowed ones too): the row's, at once.
    size_t in_range = 0;
    for (int u = 0; u < w; ++u) in_range += !out_of_range(z_row[u]);
    if (noisy) unit_normal.Fill(noise.data(), in_range);
    size_t next_noise = 0;
    for (int u = 0; u < w; ++u) {
      double z = z_row[u];
      bool missing = out_of_range(z);
      if (!missing && noisy) {
        // Far side of a depth jump: the projector's pattern is shadowed there.
        const float neighbours[4] = {u > 0 ? z_row[u - 1] : z_row[u],
                                     u + 1 < w ? z_row[u + 1] : z_row[u],
                                     v > 0 ? view.depth.ptr<float>(v - 1)[u] : z_row[u],
                                     v + 1 < h ? view.depth.ptr<float>(v + 1)[u] : z_row[u]};
        for (float n : neighbours) {
          if (n > 0 && z - n > options.silhouette_jump * z) missing = true;
        }
        const double sigma = options.depth_noise_a + options.depth_noise_b * (z - 0.4) * (z - 0.4);
        z += sigma * noise[next_noise++];
        if (options.depth_distortion != 0) {
          const double du = (u - 0.5 * (w - 1)) / (0.5 * w), dv = (v - 0.5 * (h - 1)) / (0.5 * h);
          const double rho2 = (du * du * w * w + dv * dv * h * h) / (w * w + h * h);
          z *= 1.0 + options.depth_distortion * rho2;
        }
      }
      const double raw = std::round(z * camera.depth_factor);
      d[u] = missing || raw <= 0 || raw > 65535 ? 0 : static_cast<uint16_t>(raw);
    }
  }
  return out;
}

}  // namespace sdoslam::synth
