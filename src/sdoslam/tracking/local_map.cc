#include "sdoslam/tracking/local_map.h"

#include <map>
#include <set>

namespace sdoslam {

LocalMap FindLocalMap(const Map& map, const Frame& frame) {
  LocalMap local_map;
  // Local keyframes: those that see the matched points, plus their best neighbours.
  std::map<uint64_t, int> votes;
  for (MapPoint* p : frame.map_points) {
    if (p == nullptr || p->bad) continue;
    for (const auto& [kf_id, obs] : p->observations) ++votes[kf_id];
  }
  std::vector<KeyFrame*>& local = local_map.keyframes;
  std::set<uint64_t> in_local;
  KeyFrame* best = nullptr;
  int best_votes = 0;
  for (const auto& [kf_id, count] : votes) {
    KeyFrame* kf = map.keyframes().at(kf_id).get();
    if (kf->bad) continue;
    local.push_back(kf);
    in_local.insert(kf_id);
    if (count > best_votes) {
      best_votes = count;
      best = kf;
    }
  }
  const size_t direct = local.size();
  for (size_t k = 0; k < direct && local.size() < 80; ++k) {
    for (KeyFrame* neighbour : local[k]->Covisible(10)) {
      if (!neighbour->bad && in_local.insert(neighbour->id).second) local.push_back(neighbour);
    }
    if (local[k]->parent != nullptr && !local[k]->parent->bad &&
        in_local.insert(local[k]->parent->id).second) {
      local.push_back(local[k]->parent);
    }
  }
  local_map.reference = best;

  // Local points.
  std::set<uint64_t> seen;
  for (KeyFrame* kf : local) {
    for (MapPoint* p : kf->frame.map_points) {
      if (p != nullptr && !p->bad && seen.insert(p->id).second) local_map.points.push_back(p);
    }
  }
  return local_map;
}

}  // namespace sdoslam
