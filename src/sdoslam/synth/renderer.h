#pragma once

#include <opencv2/core.hpp>

#include "sdoslam/core/camera.h"
#include "sdoslam/synth/scene.h"

namespace sdoslam::synth {

// A noise-free rendering: what a perfect sensor would see.
struct RenderedView {
  cv::Mat colour;    // CV_32FC3, BGR, linear in [0, 1], Lambertian shading
  cv::Mat depth;     // CV_32FC1, metres along the optical axis; 0 where nothing was hit
  cv::Mat instance;  // CV_16UC1, object id; 0 for the static structure
};

// Ray-casts `scene` at time t (seconds from the sequence start) through every pixel centre of
// `camera` placed at T_world_camera. Rows are rendered in parallel; every pixel depends only on
// the inputs, so the result is the same whatever the number of threads.
RenderedView Render(const Scene& scene, double t, const Eigen::Isometry3d& T_world_camera,
                    const Camera& camera);
// An image-sized view for RenderRows to fill (contents undefined).
RenderedView AllocateView(const Camera& camera);
// Render's rows [row_begin, row_end) into `view` (from AllocateView); the other rows are left
// as they are. A rolling shutter renders its bands this way.
void RenderRows(const Scene& scene, double t, const Eigen::Isometry3d& T_world_camera,
                const Camera& camera, int row_begin, int row_end, RenderedView* view);

// The colour image as a camera records it: each pixel averages samples_per_side² rays spread
// evenly over its area (a box filter, as a photosite integrates the light that falls on it).
// With one ray per pixel (samples_per_side = 1: Render's colour) the sharp edges of the
// procedural texture alias: a corner on them moves by whole pixels from frame to frame, and
// every frame's pose jitters with it; 2 × 2 rays take part of that away (docs/results.md, Long
// runs). Costs samples_per_side² renderings.
cv::Mat RenderColour(const Scene& scene, double t, const Eigen::Isometry3d& T_world_camera,
                     const Camera& camera, int samples_per_side);

}  // namespace sdoslam::synth
