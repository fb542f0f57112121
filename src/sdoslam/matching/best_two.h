#pragma once

namespace sdoslam {

// The nearest and second-nearest of a set of candidate descriptors, by Hamming distance: the
// one loop that every descriptor search runs (projection and local-map search, brute-force
// search, fusion, triangulation's epipolar search). Add each candidate's distance in the order
// the search meets them; a tie keeps the candidate met first.
//
// Distances start at 256, a 256-bit descriptor's largest distance, and a candidate counts only
// when strictly nearer: one at 256 (every bit differs) is never taken. Every search rejects such
// a match by its threshold anyway.
struct BestTwo {
  int best = 256, second = 256;
  int best_index = -1, second_index = -1;  // -1: none yet

  void Add(int distance, int index) {
    if (distance < best) {
      second = best;
      second_index = best_index;
      best = distance;
      best_index = index;
    } else if (distance < second) {
      second = distance;
      second_index = index;
    }
  }

  bool found() const { return best_index >= 0; }

  // Lowe's ratio test fails: the best is not clearly nearer than the second (best > ratio ×
  // second). Repetitive texture gives look-alikes, and then the nearest is a guess.
  bool Ambiguous(double ratio) const { return best > ratio * second; }
};

}  // namespace sdoslam
