#pragma once

#include <atomic>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/map/map.h"
#include "sdoslam/optim/optimizer.h"

namespace sdoslam {

struct LocalMapperOptions {
  int fuse_neighbours = 10;           // covisible keyframes searched for duplicate points
  int triangulation_neighbours = 10;  // covisible keyframes to triangulate new points with
  double min_found_ratio = 0.25;      // recent points found less often than this are culled
  double redundant_ratio = 0.9;       // keyframes with this share of redundant points are culled
  // In that share, points past their probation that at most this many keyframes observe do not
  // count: a place seen once or twice is a mover's trace or noise, and would keep its keyframe
  // forever (ORB-SLAM2: 0). Measured in docs/results.md, Long runs.
  int transient_observations = 2;
  // Keyframes per place: when a keyframe is inserted, the older ones within `crowded_distance`
  // metres and `crowded_angle_deg` of its view make a crowd, and past `crowded_keyframes` the most
  // redundant are culled. Where tracking stays weak nearly every frame becomes a keyframe, and a
  // camera that never leaves a room would grow its map without end. A place is a whole room
  // view, not a few centimetres: sdo's keyframes on slow footage lie 1 cm apart.
  double crowded_distance = 1.0;
  double crowded_angle_deg = 60;
  int crowded_keyframes = 30;
  // The local window, so that a keyframe's cost follows the place, not the run's length: local BA
  // refines the new keyframe and its `local_keyframes` most covisible neighbours, holding fixed
  // the `fixed_keyframes` other keyframes that observe most of the window's points; observations
  // from keyframes outside both are left out. 10, not ORB-SLAM2's 20: where movers hide much of
  // the room sdo makes a keyframe every 3 frames.
  int local_keyframes = 10;
  int fixed_keyframes = 10;
  // A local BA's cost follows its observations, which keep growing in a room the camera never
  // leaves: the window takes neighbours (up to three quarters of this budget), then fixed
  // keyframes while their observations fit. Keeps mapping time flat over long runs
  // (docs/results.md, Long runs).
  int max_ba_observations = 8000;
  BundleAdjustmentOptions bundle_adjustment;
  // Threaded runs (System): false, local mapping and loop closing run in tracking's thread right
  // after the keyframe is made, while the next frames are read and prepared ahead, so a threaded
  // run's trajectory is the sequential run's bit for bit. true: they run in threads of their own
  // beside tracking (ORB-SLAM2's design), tracking goes on while a keyframe is mapped, and runs
  // vary. On two cores the preparing stage already keeps both cores busy: true was at most 9 %
  // faster, and on fast hand-held turns it tracked against a map that lagged behind
  // (docs/performance.md).
  // The settings below marked "concurrent mapping" apply only with true.
  bool concurrent = false;
  // Concurrent mapping: tracking makes no keyframe while this many wait for local mapping.
  int max_queued_keyframes = 3;
  // Concurrent mapping: tracking waits before frame k while local mapping has not finished a
  // keyframe made before frame k − max_tracking_lead (0: never waits). Read from files, tracking
  // outruns mapping and leans on a map that lags behind a fast-turning view; a camera gives
  // mapping that time, and so does this bound, without sleeping when mapping keeps up
  // (docs/configuration.md).
  int max_tracking_lead = 1;
  // Concurrent mapping: a keyframe that arrives while local BA solves stops it after the iteration
  // under way (its solution so far is kept), and one already waiting when the BA would start
  // skips it, as ORB-SLAM2's local mapping does: the next keyframe's BA covers nearly the same
  // window. Sequential runs never stop a BA.
  bool stop_ba_for_new_keyframe = true;
  // A keyframe made fewer than this many frames after the last keyframe whose local BA ran gets
  // none (0 or 1: every keyframe gets one): where movers hide much of the room sdo makes a
  // keyframe every second frame, and each BA would solve almost the window of the one before.
  // 3 saves 40 % of local BA's work at the same accuracy (docs/performance.md).
  int min_frames_between_local_ba = 3;
  void Check(const std::string& path = "mapping.") const;  // Error names path + setting
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("fuse_neighbours", o.fuse_neighbours);
    visit("triangulation_neighbours", o.triangulation_neighbours);
    visit("min_found_ratio", o.min_found_ratio);
    visit("redundant_ratio", o.redundant_ratio);
    visit("transient_observations", o.transient_observations);
    visit("crowded_distance", o.crowded_distance);
    visit("crowded_angle_deg", o.crowded_angle_deg);
    visit("crowded_keyframes", o.crowded_keyframes);
    visit("local_keyframes", o.local_keyframes);
    visit("fixed_keyframes", o.fixed_keyframes);
    visit("max_ba_observations", o.max_ba_observations);
    visit("bundle_adjustment", o.bundle_adjustment);
    visit("concurrent", o.concurrent);
    visit("max_queued_keyframes", o.max_queued_keyframes);
    visit("max_tracking_lead", o.max_tracking_lead);
    visit("stop_ba_for_new_keyframe", o.stop_ba_for_new_keyframe);
    visit("min_frames_between_local_ba", o.min_frames_between_local_ba);
  }
};

// Statistics of one processed keyframe, for the run log.
struct MappingResult {
  int culled_points = 0;
  int triangulated_points = 0;
  int fused_points = 0;
  int local_keyframes = 0, fixed_keyframes = 0, local_points = 0;
  BundleAdjustmentStats ba;  // observations, solver iterations and stop of the local BA
  // No local BA was run because a new keyframe was waiting (threaded: it gave way).
  bool ba_skipped = false;
  // No local BA was run because one ran fewer than min_frames_between_local_ba frames before
  // (the next adjusted keyframe's window covers this one). Kept apart from ba_skipped, so that
  // mapping.csv tells a threaded run's give-way from the spacing every run has.
  bool ba_spaced = false;
  int removed_observations = 0;
  int culled_keyframes = 0;
  int freed_points = 0;  // culled points whose memory was released
  // Milliseconds per stage: keyframe insertion and point culling, triangulation, fusion, local
  // bundle adjustment (its solve without the map lock), keyframe culling.
  double insert_ms = 0, triangulate_ms = 0, fuse_ms = 0, ba_ms = 0, ba_solve_ms = 0, cull_ms = 0;
  double lock_wait_ms = 0;    // threaded: waiting for the map while tracking held it
  bool ba_discarded = false;  // threaded: loop closing moved the map during the solve
};

// ORB-SLAM's local mapping for RGB-D: insert a keyframe (observations, covisibility), cull
// recent points that are rarely found, fuse duplicates with the neighbours, local bundle
// adjustment (neighbours free, their other observers fixed), cull redundant keyframes.
class LocalMapper {
 public:
  LocalMapper(Map* map, const LocalMapperOptions& options);
  // Processes a new keyframe. Keyframes must come in the order they were made. With
  // `map_mutex`, the map is locked while it is read or changed, but not while the bundle
  // adjustment is solved (on a copy), so tracking goes on meanwhile. `new_keyframe_waiting`
  // (threaded, with options.stop_ba_for_new_keyframe): raised by the caller when another
  // keyframe is queued; it skips or stops the local BA.
  MappingResult Process(KeyFrame* keyframe, std::mutex* map_mutex = nullptr,
                        const std::atomic<bool>* new_keyframe_waiting = nullptr);

 private:
  void InsertKeyFrame(KeyFrame* keyframe);
  int CullRecentPoints(KeyFrame* keyframe);
  int TriangulateNewPoints(KeyFrame* keyframe);
  int FuseWithNeighbours(KeyFrame* keyframe);
  // The keyframe and its most covisible neighbours, at most options_.local_keyframes of them.
  std::vector<KeyFrame*> LocalWindow(KeyFrame* keyframe) const;
  void LocalBundleAdjustment(KeyFrame* keyframe, MappingResult* result, std::mutex* map_mutex,
                             const std::atomic<bool>* stop);
  // The local BA's window: the keyframes it refines, their points, and the keyframes it holds
  // fixed, within the observation budget (max_ba_observations).
  struct BaWindow {
    std::vector<KeyFrame*> local, fixed;
    std::vector<MapPoint*> points;
  };
  BaWindow SelectBaWindow(KeyFrame* keyframe) const;
  // One observation of the problem: which point, seen by which keyframe.
  struct BaLink {
    MapPoint* point;
    KeyFrame* keyframe;
  };
  // The window as a problem for BundleAdjust; `links`: its observations, in the problem's order.
  static BundleAdjustmentProblem MakeBaProblem(const BaWindow& window, std::vector<BaLink>* links);
  // Writes the solution back to what still exists, and drops the outlier observations.
  void WriteBackBa(const BaWindow& window, const BundleAdjustmentProblem& solved,
                   const std::vector<bool>& inlier, const std::vector<BaLink>& links,
                   MappingResult* result);
  int CullKeyFrames(KeyFrame* keyframe);
  int CullCrowdedKeyFrames(KeyFrame* keyframe);
  struct Redundancy {
    int points = 0;     // map points that count (transient ones do not)
    int redundant = 0;  // of those, seen by three other keyframes at the same or a finer scale
  };
  Redundancy RedundantPoints(const KeyFrame* candidate, const KeyFrame* keyframe) const;

  Map* map_;
  LocalMapperOptions options_;
  std::vector<MapPoint*> recent_points_;
  std::optional<size_t> last_adjusted_frame_;  // frame index of the last keyframe adjusted
};

}  // namespace sdoslam
