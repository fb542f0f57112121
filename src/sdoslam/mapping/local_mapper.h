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
  // In that share, points past their probation (three keyframes) that at most this many keyframes
  // observe do not count: a place seen once or twice is a mover's trace or noise, and would keep
  // its keyframe forever. ORB-SLAM2 counts every point (0 here). With 2, a conventional run among
  // walking people keeps 88 keyframes at frame 1,000 instead of 340 (README.md's git history, Long
  // runs); sdo's maps, where movers leave no points, barely change.
  int transient_observations = 2;
  // A bound on keyframes per viewpoint, for maps that the rules above leave growing: where
  // tracking stays weak (conventional mode among walking people) nearly every frame becomes a
  // keyframe, each holds points that keep it, and a camera that never left one room had 88
  // keyframes alive at frame 1,000 and 162 at 3,000. So when a keyframe is inserted, the older
  // keyframes whose camera lies within `crowded_distance` metres of its own and looks within
  // `crowded_angle_deg` of its direction make a crowd; past `crowded_keyframes` (the new one
  // included), the members with the largest share of redundant points are culled, the older
  // first on a tie. A fixed distance is wrong for small moves: in the real-background plays
  // (a desk recording played forward and back) sdo's keyframes lie 1 cm apart and a crowd of
  // 3 within 5 cm cost 84 -> 97 mm summed, so the crowd is a whole place (1 m, 60 degrees) and
  // its quota above what sdo's maps hold there (18-27 keyframes alive). 0 turns the rule off.
  double crowded_distance = 1.0;
  double crowded_angle_deg = 60;
  int crowded_keyframes = 30;
  // The local window, so that a keyframe's cost follows the place, not the length of the run: local
  // BA refines the new keyframe and its `local_keyframes` most covisible neighbours (keyframe
  // culling looks at those same neighbours), holding fixed the `fixed_keyframes` other keyframes
  // that observe most of the window's points. Observations from keyframes outside both sets are
  // left out of the adjustment. 10 rather than 20: where movers hide much of the room, sdo makes a
  // keyframe every 3 frames, and 20 neighbours made each BA cost 30+ ms; with 10, sdo's ATE over 13
  // real-frame sequences is 68.9 against 70.6 mm summed, and the 3,000-frame walking_xyz soak's
  // keyframes 2.8 against 3.5 mm (README.md's git history, Long runs).
  int local_keyframes = 10;
  int fixed_keyframes = 10;
  // A local BA's cost follows its observations. In a room the camera never leaves, the bounded
  // map's points keep gaining observers: a window of 20 keyframes grew from 9,000 to 11,400
  // observations over 3,000 frames, and its BA from 77 to 110 ms. So the window takes
  // neighbours (most covisible first, up to three quarters of this budget) and then fixed
  // keyframes only while their observations stay within it. 8,000 rather than 10,000: over
  // 3,000 frames of walking_xyz (sdo) it holds the mapping time flat after the first 500 frames
  // (median 58 -> 71 ms sequential, 62 -> 78 threaded, against 60 -> 85 and 75 -> 131) with
  // the same frame ATE (5.3 against 5.2 mm); static_room's frames stay at 4.2 mm.
  int max_ba_observations = 8000;
  BundleAdjustmentOptions bundle_adjustment;
  // Threaded mapping (System): tracking makes no keyframe while this many wait for local mapping.
  int max_queued_keyframes = 3;
  // Threaded mapping: tracking waits before frame k while local mapping has not finished a
  // keyframe made before frame k − max_tracking_lead (0: never waits). Read from files, tracking
  // outruns mapping: it tracks a frame in 10-20 ms where a camera gives one every 33, mapping a
  // keyframe takes 30-60 ms, and on fast hand-held motion tracking then leans on a map that lags
  // behind the view, skips keyframes while mapping is busy and stops its bundle adjustments.
  // A camera gives mapping that time; so does this bound, without sleeping when mapping keeps up.
  int max_tracking_lead = 1;
  // Threaded mapping: a keyframe that arrives while local BA solves stops it after the iteration
  // under way (its solution so far is kept), and a keyframe already waiting when the BA would
  // start skips it, as ORB-SLAM2's local mapping does: the next keyframe's BA covers nearly the
  // same window. Where movers hide much of the room sdo makes a keyframe every 3 frames and each
  // BA took 30-70 ms of CPU (mapping.csv, the mixed play threaded). Sequential runs never stop a
  // BA.
  bool stop_ba_for_new_keyframe = true;
  // A keyframe made fewer than this many frames after the last keyframe whose local BA ran gets
  // none (0 or 1: every keyframe gets one); the next keyframe's BA covers nearly the same window.
  // 3: where movers hide much of the room sdo makes a keyframe every second frame, and each BA then
  // solves almost the window of the one before. On the mixed play 27 keyframes get 20 BAs instead
  // of 25-27, local BA's instructions fall 40 % (callgrind, 40 frames: 2.58 -> 1.55 G) and threaded
  // sdo's process CPU 7 % (3.12 -> 2.90 s, medians of 5); accuracy the same (scripts/plays.sh 79.7
  // -> 79.6 mm, held-out seeds 4-6 49.8 -> 49.6, fr2_desk_50 byte for byte, 3,000 frames of
  // walking_xyz 4.4 -> 4.6 mm). 5: the plays 79.3 but the held-out seeds 50.7 (person_fills_view
  // seed 4 5.3 -> 6.6). README.md's git history, "Local BA once in three frames".
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
