#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace sdoslam {

using WordId = uint32_t;

// Sparse bag-of-words vector: word -> TF-IDF weight, L1-normalised (the weights sum to 1).
// A std::map so that iteration is ordered and every result built from it is deterministic.
using BowVector = std::map<WordId, double>;

// Direct index: node id `levels_up` levels above the leaves -> indices of the features below it
// (ascending). For vocabulary-guided matching: only features under the same node are compared.
using FeatureVector = std::map<uint32_t, std::vector<int>>;

// The largest vocabulary file read or written: 2 * 10^7 words at branching 10 (ORB-SLAM's has
// 10^6 in 45 MB). A sanity limit, so that a wrong file fails with its size instead of being
// read into memory first.
inline constexpr uint64_t kMaxVocabularyBytes = uint64_t{1} << 30;

struct VocabularyOptions {
  int branching = 10;  // children per node (k of the k-medians)
  int depth = 4;       // levels below the root: at most branching^depth words
  // Assignment/update rounds of k-medians per node; the clustering stops earlier when no
  // descriptor changes cluster. Binary k-medians settles within a handful of rounds, and the
  // first rounds move the centres most (DBoW2 runs to convergence; 10 costs little).
  int kmeans_iterations = 10;
  uint32_t seed = 1;  // of the k-means++ seeding
  void Check() const;
};

// A vocabulary of binary words for 256-bit ORB descriptors: the tree of DBoW2 (Gálvez-López &
// Tardós 2012), as ORB-SLAM uses it for place recognition, written for this project.
// (OpenCV's BOWKMeansTrainer and BOWImgDescriptorExtractor cluster float descriptors with the
// Euclidean distance only, which is why the binary version is written by hand here.)
//
// Each inner node has up to `branching` children, each with a 256-bit centre; a descriptor
// descends from the root to the child whose centre is nearest in Hamming distance, down to a
// leaf: its word. Each word carries an IDF weight learnt from the training images.
// Immutable once built; Transform and Score may be called from any number of threads.
class Vocabulary {
 public:
  Vocabulary() = default;  // empty (size() == 0); Transform throws on it

  // descriptor_sets: one N x 32 CV_8U matrix (256-bit ORB) per training image. Hierarchical
  // k-medians (centres are bitwise majorities, the binary counterpart of the mean) seeded by
  // greedy k-means++ from a std::mt19937 with options.seed, node by node breadth-first; a node
  // stays a leaf at `depth`, or when its descriptors are all alike. Word IDF weight =
  // log(N_images / N_images containing the word), N_images counting every set given, empty
  // ones too. Deterministic for a given seed and input. Throws Error for bad options, a matrix
  // of the wrong type, or fewer than two images with descriptors.
  static Vocabulary Train(const std::vector<cv::Mat>& descriptor_sets,
                          const VocabularyOptions& options);

  // The binary format Save writes. Throws Error naming the file when it is missing, not a
  // regular file, larger than kMaxVocabularyBytes, truncated, not a vocabulary (magic), of
  // another format version, or corrupt (checksum).
  static Vocabulary Load(const std::string& path);
  // The same format from memory; `name` stands for the file in messages.
  static Vocabulary FromBytes(const void* data, size_t size, const std::string& name);
  // Written atomically (core/atomic_file.h); throws IoError when it cannot be written, Error
  // when it would be larger than kMaxVocabularyBytes (Load would refuse it).
  void Save(const std::string& path) const;
  std::string ToBytes() const;  // what Save writes

  size_t size() const { return weights_.size(); }  // number of words (leaves)
  int depth() const { return depth_; }
  int branching() const { return branching_; }
  size_t nodes() const { return child_count_.size(); }  // root included
  // What the vocabulary was trained on (stored in the file, for `sdoslam vocab info`).
  uint32_t training_images() const { return training_images_; }
  uint64_t training_descriptors() const { return training_descriptors_; }
  double weight(WordId word) const { return weights_.at(word); }  // IDF

  // The word of one descriptor (32 bytes).
  WordId WordOf(const uint8_t* descriptor) const;

  // Words of each descriptor row; `bow` receives their TF-IDF vector, L1-normalised (words
  // whose IDF is 0, seen in every training image, carry no weight and are left out; no
  // descriptors give an empty vector). `features` (optional) receives, for every row, the node
  // `levels_up` levels above the leaves on the row's path (the leaf itself where the path
  // ends higher up; the root when levels_up >= depth). Throws Error unless `descriptors` is
  // empty or CV_8U with 32 columns.
  void Transform(const cv::Mat& descriptors, BowVector* bow, FeatureVector* features = nullptr,
                 int levels_up = 2) const;

  // DBoW2's L1 score: 1 - 0.5 * |a/|a| - b/|b||_1, in [0, 1]; 1 for identical vectors, 0 for
  // vectors with no word in common (and when either is empty).
  static double Score(const BowVector& a, const BowVector& b);

 private:
  static constexpr uint32_t kNoWord = UINT32_MAX;
  // first_child_, word_ and word_count_ from child_count_ (nodes are stored breadth-first).
  void Index();

  int branching_ = 0;
  int depth_ = 0;
  uint32_t training_images_ = 0;
  uint64_t training_descriptors_ = 0;
  // Node i's centre is centres_[32 i, 32 i + 32): the children of a node are consecutive, so
  // the descent reads one contiguous block per level. Node 0 is the root (no centre).
  std::vector<uint8_t> centres_;
  std::vector<uint8_t> child_count_;   // 0 for leaves
  std::vector<uint32_t> first_child_;  // derived
  std::vector<uint32_t> word_;         // derived: word of a leaf, kNoWord for inner nodes
  uint32_t word_count_ = 0;            // derived: leaves
  std::vector<double> weights_;        // IDF per word
};

}  // namespace sdoslam
