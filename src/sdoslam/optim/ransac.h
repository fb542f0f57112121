#pragma once

#include <concepts>
#include <optional>
#include <utility>

namespace sdoslam {

// What the RANSAC loop needs of a problem: a hypothesis from a minimal sample it draws itself
// (nullopt for a degenerate sample, which still counts as an iteration), a score, which of two
// scores is better, a local optimisation of a new best (LO-RANSAC; may do nothing), and how many
// samples to draw in all given the best score so far (adaptive, or a fixed count).
template <class P>
concept RansacProblem = requires(P problem, const typename P::Model& model,
                                 typename P::Model* mutable_model, const typename P::Score& score,
                                 typename P::Score* mutable_score) {
  { problem.Hypothesis() } -> std::same_as<std::optional<typename P::Model>>;
  { problem.Evaluate(model) } -> std::same_as<typename P::Score>;
  { problem.Better(score, score) } -> std::same_as<bool>;
  {problem.Improve(mutable_model, mutable_score)};
  { problem.Iterations(score) } -> std::same_as<int>;
  { problem.Worst() } -> std::same_as<typename P::Score>;
};

template <class Model, class Score>
struct RansacOutcome {
  std::optional<Model> model;  // the best hypothesis after its local optimisation; none found
  Score score;
  int iterations = 0;  // samples drawn, degenerate ones included
};

// The hypothesise-and-verify loop shared by the 3-D–3-D RANSAC of loop verification and
// relocalisation (rigid_ransac.h) and the static world's motion (tracking/static_motion.h).
// Written here rather than taken from OpenCV: cv::estimateAffine3D and solvePnPRansac fix the
// score, the sampler and the stopping rule, and both users need their own (a depth-dependent
// threshold with an MSAC tie-break; LO-RANSAC on a pixel threshold), with a seeded sampler
// whose draws are the same on every platform. The problem draws its own samples, so the sequence
// of draws (and the result) is the problem's alone.
template <RansacProblem Problem>
RansacOutcome<typename Problem::Model, typename Problem::Score> Ransac(Problem& problem) {
  RansacOutcome<typename Problem::Model, typename Problem::Score> outcome{
      .model = std::nullopt, .score = problem.Worst(), .iterations = 0};
  int needed = problem.Iterations(outcome.score);
  while (outcome.iterations < needed) {
    ++outcome.iterations;
    std::optional<typename Problem::Model> model = problem.Hypothesis();
    if (!model) continue;
    typename Problem::Score score = problem.Evaluate(*model);
    if (!problem.Better(score, outcome.score)) continue;
    problem.Improve(&*model, &score);
    outcome.model = std::move(model);
    outcome.score = std::move(score);
    needed = problem.Iterations(outcome.score);
  }
  return outcome;
}

}  // namespace sdoslam
