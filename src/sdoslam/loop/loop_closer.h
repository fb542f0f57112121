#pragma once

#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "sdoslam/map/map.h"
#include "sdoslam/optim/optimizer.h"
#include "sdoslam/optim/pose_graph.h"
#include "sdoslam/optim/rigid_ransac.h"
#include "sdoslam/place/keyframe_places.h"

namespace sdoslam {

struct LoopClosingOptions {
  bool enabled = true;
  // No loop is looked for in the first keyframes of a run nor within this many keyframes of
  // the last loop closed (ORB-SLAM2: 10): a fresh map has nothing to close, and a loop just
  // closed would be found again.
  int min_keyframes_between = 10;
  // A candidate is taken only when the groups around it (the candidate and its covisible
  // keyframes) were found for this many consecutive keyframes after the first: one look-alike
  // keyframe is not a loop. ORB-SLAM2 asks 3, with a keyframe every few frames; this tracker
  // makes one every 30-50 frames where the view is full of close points (the long loop: 19 in
  // 700 frames), so 3 would ask for 4-6 s of revisit. The geometric check (RANSAC, then 40
  // inliers after a projection search) guards against look-alikes.
  int consistent_detections = 1;
  // Geometric verification: descriptor matches with the candidate's map points, inliers of the
  // 3-D–3-D RANSAC and of the pose optimisation, then matches with the whole loop side
  // projected at the corrected pose.
  int min_matches = 20;
  // The descriptor matches are sought in the candidate and its this many most covisible
  // keyframes, each map point once (ORB-SLAM3's common-region search; ORB-SLAM2 matches the
  // candidate alone). A keyframe made in a fast turn shares few points with any one old
  // keyframe: over 20 feature counts of the real fr1_rpy clip, conventional closed the loop back
  // to the start on 8 runs, on 18 with 5 neighbours (sdo: 17, 18).
  int verify_neighbours = 5;
  int min_inliers = 20;
  int min_projected_inliers = 40;
  // A verified loop that would move the keyframe by less than both of these is not closed: the
  // map already agrees there (tracking or relocalization found the old points; a mover hid the
  // links), and closing it would block detection for min_keyframes_between keyframes, the real
  // loop after it among them. On the fr1_rpy plays with movers, 38 of 68 loops closed moved
  // the keyframe by under 1 cm.
  double min_correction_m = 0.01;
  double min_correction_deg = 1.0;
  // Essential graph: covisibility edges of at least this weight (shared points) join the
  // spanning tree and the loop edges in the pose graph (ORB-SLAM2: 100).
  int essential_min_weight = 100;
  // ... the strongest this many per keyframe, to older keyframes; and of the links a loop
  // makes, the strongest this many per keyframe it moved. The pose graph's cost follows
  // its edges: where conventional mode tracks people as static, nearly every frame becomes a
  // keyframe, and without the cap a closure's graph took minutes to solve.
  int essential_max_covisible = 10;
  // A closed loop fuses the loop side's points (the loop keyframe's and those of its strongest
  // this many covisible keyframes) into the closing keyframe and its strongest this many
  // (ORB-SLAM2: every covisible keyframe on both sides), and reconnects only those. Where
  // conventional mode keeps nearly every keyframe, a keyframe had hundreds of covisible ones
  // and a closure took a minute; sdo's and static scenes' maps keep fewer keyframes alive
  // (13-35) than the cap.
  int fuse_keyframes = 50;
  RigidRansacOptions ransac;
  PoseGraphOptions pose_graph;
  // After the pose graph, a bundle adjustment of every keyframe and point (ORB-SLAM2's global
  // BA): the pose graph moves keyframes as rigid bodies, the BA then fits them to the points
  // both visits see. Threaded, it is solved without the map lock.
  bool global_bundle_adjustment = true;
  BundleAdjustmentOptions global_ba{10, 10};
  // A global BA over more observations than this is not run; the pose graph's correction
  // stands (loops.csv says so). Its cost grows faster than the map: a fraction of a second for
  // the long loop's 5,100 observations (docs/results.md, Loop closing), but minutes, with a
  // sequential run's tracking stopped meanwhile, where conventional mode lets the map grow with
  // people tracked as static. sdo's 3,000-frame runs keep 13-35 keyframes alive.
  int max_global_ba_observations = 100000;
  void Check(const std::string& path = "loop_closing.") const;  // Error names path + setting
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("enabled", o.enabled);
    visit("min_keyframes_between", o.min_keyframes_between);
    visit("consistent_detections", o.consistent_detections);
    visit("min_matches", o.min_matches);
    visit("verify_neighbours", o.verify_neighbours);
    visit("min_inliers", o.min_inliers);
    visit("min_projected_inliers", o.min_projected_inliers);
    visit("min_correction_m", o.min_correction_m);
    visit("min_correction_deg", o.min_correction_deg);
    visit("essential_min_weight", o.essential_min_weight);
    visit("essential_max_covisible", o.essential_max_covisible);
    visit("fuse_keyframes", o.fuse_keyframes);
    visit("ransac", o.ransac);
    visit("pose_graph", o.pose_graph);
    visit("global_bundle_adjustment", o.global_bundle_adjustment);
    visit("global_ba", o.global_ba);
    visit("max_global_ba_observations", o.max_global_ba_observations);
  }
};

// One loop closed, for the run log.
struct LoopRecord {
  size_t frame_index = 0;       // the frame of the keyframe that closed the loop
  size_t loop_frame_index = 0;  // the frame of the keyframe it closed on (the revisited place)
  uint64_t keyframe_id = 0, loop_keyframe_id = 0;
  int matches = 0, inliers = 0, projected_inliers = 0;
  int fused_points = 0;
  int graph_keyframes = 0, graph_edges = 0;
  double correction_m = 0;  // how far the keyframe moved, metres
  double ms = 0;            // the whole closure, global BA included
  // Its stages: the geometric check of the candidates, moving the keyframe's neighbourhood
  // and fusing the loop side's points into it, the pose graph (built and solved), and moving
  // every point with its keyframe.
  double verify_ms = 0, fuse_ms = 0, pose_graph_ms = 0, points_ms = 0;
  int global_ba_observations = 0;    // of the global BA, run or not
  double global_ba_ms = 0;           // 0: not run
  bool global_ba_skipped = false;    // more observations than max_global_ba_observations
  bool global_ba_discarded = false;  // threaded: the map was corrected again meanwhile
};

// Whether a loop that moves a keyframe's pose from T_camera_world to corrected_T_camera_world
// corrects enough to be closed: its centre by min_correction_m or its orientation by
// min_correction_deg.
bool CorrectsEnough(const LoopClosingOptions& options, const Eigen::Isometry3d& T_camera_world,
                    const Eigen::Isometry3d& corrected_T_camera_world);

// What the loop closer did with one keyframe.
struct LoopResult {
  bool detected = false;  // a candidate passed the consistency test
  bool closed = false;    // ... and the geometric check, and the map was corrected
  LoopRecord record;
  double detect_ms = 0;
};

// ORB-SLAM2's loop closing for RGB-D (SE(3): depth fixes the scale): after local mapping, each
// keyframe is looked up among the keyframes not connected to it; a candidate found for
// consistent_detections keyframes in a row is checked geometrically (descriptor matches, 3-D–3-D
// RANSAC, pose optimisation, a projection search of the loop side); then the keyframe and its
// neighbours are moved to the loop, duplicated points fused, and the pose graph over the
// essential graph spreads the correction over the map.
class LoopCloser {
 public:
  LoopCloser(Map* map, KeyFramePlaces* places, const LoopClosingOptions& options);

  // Processes a keyframe that local mapping has finished. Without `map_mutex` (sequential) it
  // runs as one step. With it (threaded), detection holds the lock briefly, and the correction
  // waits, lock held, until `between_frames` says tracking is not inside a frame (`frame_done`
  // is notified when that changes), so that no frame is half in the old map and half in the
  // new.
  LoopResult Process(KeyFrame* keyframe, std::mutex* map_mutex = nullptr,
                     std::condition_variable* frame_done = nullptr,
                     const std::function<bool()>& between_frames = {});

 private:
  struct Group {
    std::set<uint64_t> keyframes;
    int consistency = 0;
  };
  // Candidates that passed the consistency test.
  std::vector<KeyFrame*> DetectCandidates(KeyFrame* keyframe, const BowVector& bow);
  // The places among the keyframes found (id -> score) that score within 75 % of the best,
  // each counted with its covisible neighbours found too (ORB-SLAM2's accumulated score) and
  // represented by the best-scoring keyframe in it.
  std::vector<KeyFrame*> Representatives(const std::map<uint64_t, double>& score) const;
  // The representatives whose group (with its covisible keyframes) continues a group of the
  // previous keyframes consistent_detections times; keeps this keyframe's groups for the next.
  std::vector<KeyFrame*> ConsistentCandidates(const std::vector<KeyFrame*>& representatives);
  struct Verified {
    KeyFrame* loop = nullptr;
    Eigen::Isometry3d T_camera_world = Eigen::Isometry3d::Identity();  // keyframe's, corrected
    std::vector<MapPoint*> matched;  // per feature of the keyframe: the loop side's point
    int matches = 0, inliers = 0, projected_inliers = 0;
  };
  bool Verify(KeyFrame* keyframe, KeyFrame* candidate, Verified* verified);
  // The steps of Verify. Descriptor matches of the keyframe's features with the map points of
  // the candidate and its verify_neighbours most covisible keyframes, in `probe` (a copy of
  // the keyframe's frame, its map points cleared): a feature keeps its first match, a point
  // matches one feature. Returns the number of matches.
  int MatchPlace(KeyFrame* keyframe, KeyFrame* candidate, Frame* probe) const;
  void Correct(KeyFrame* keyframe, const Verified& verified, LoopRecord* record);
  // The steps of Correct. Moves the keyframe to its corrected pose `T_camera_world`, and its
  // covisible keyframes (their ids into `connected_ids`) and their points rigidly with it;
  // returns, per point moved, the keyframe whose move it followed.
  std::map<uint64_t, uint64_t> MoveToLoop(KeyFrame* keyframe,
                                          const Eigen::Isometry3d& T_camera_world,
                                          std::set<uint64_t>* connected_ids);
  // Makes the matched points the loop side's, fuses the loop side's points into the keyframe's
  // neighbours, and adds the new links across the loop to loop_edges_. Returns the points fused.
  int FuseAcrossLoop(KeyFrame* keyframe, const Verified& verified,
                     const std::set<uint64_t>& connected_ids);
  // The essential graph's solution: its keyframes in `graph`'s order with their poses before it
  // was solved, and the keyframes still pending for local mapping (not in the graph).
  struct CorrectedGraph {
    PoseGraphProblem graph;
    std::vector<KeyFrame*> keyframes, pending;
    std::vector<Eigen::Isometry3d> pre_graph;
  };
  // Spreads the correction over the essential graph (the loop keyframe holds the gauge);
  // `before`: every good keyframe's pose before the loop.
  CorrectedGraph SpreadCorrection(KeyFrame* loop,
                                  const std::map<uint64_t, Eigen::Isometry3d>& before,
                                  LoopRecord* record);
  // Gives the keyframes their corrected poses (the pending ones move with `keyframe`), moves
  // every point with the keyframe it was corrected with or its reference keyframe, and notes
  // the correction in the map.
  void MovePoints(KeyFrame* keyframe, const std::map<uint64_t, Eigen::Isometry3d>& before,
                  const std::map<uint64_t, uint64_t>& corrected_by, CorrectedGraph* corrected);
  // Solved without `lock` when it holds one; written back once tracking is between frames.
  void GlobalBundleAdjustment(std::unique_lock<std::mutex>* lock,
                              std::condition_variable* frame_done,
                              const std::function<bool()>& between_frames, LoopRecord* record);
  // The solved global BA (`keyframes` and the points with ids `points`, in its order) written
  // back to what still exists; points made meanwhile follow their reference keyframe's move.
  void WriteBackGlobalBa(const std::vector<KeyFrame*>& keyframes,
                         const std::vector<uint64_t>& points, const BundleAdjustmentProblem& ba);

  Map* map_;
  KeyFramePlaces* places_;
  LoopClosingOptions options_;
  std::vector<Group> groups_;  // consistent groups of the last keyframe
  uint64_t last_loop_keyframe_ = 0;
  bool closed_any_ = false;
  // Loop edges of the essential graph: pairs of keyframe ids, kept across loops.
  std::set<std::pair<uint64_t, uint64_t>> loop_edges_;
  uint64_t search_stamp_ = 0;
};

}  // namespace sdoslam
