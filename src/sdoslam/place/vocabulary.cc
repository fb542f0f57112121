#include "sdoslam/place/vocabulary.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <deque>
#include <filesystem>
#include <iterator>
#include <optional>
#include <random>
#include <utility>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/features/orb_extractor.h"

namespace sdoslam {
namespace {

constexpr int kBytes = 32;  // 256-bit ORB descriptors

// The file: a fixed header, each node's child count (breadth-first order), each node's centre,
// each word's IDF weight, and an FNV-1a checksum of everything before it. Little-endian.
constexpr char kMagic[8] = {'S', 'D', 'O', 'S', 'V', 'O', 'C', 'B'};
constexpr uint32_t kVersion = 1;
static_assert(std::endian::native == std::endian::little,
              "the vocabulary file is read and written in host byte order");

uint64_t Fnv1a(const uint8_t* data, size_t size) {
  uint64_t hash = 1469598103934665603ULL;
  for (size_t i = 0; i < size; ++i) {
    hash ^= data[i];
    hash *= 1099511628211ULL;
  }
  return hash;
}

// Uniform draws from the raw 32-bit output of std::mt19937. The standard fixes the engine's
// sequence but not what its distributions make of it (libstdc++ and libc++ differ), so the
// mapping is written out: the same seed gives the same vocabulary with any standard library.
uint32_t UniformBelow(std::mt19937& rng, uint32_t n) {
  return static_cast<uint32_t>((static_cast<uint64_t>(rng()) * n) >> 32);
}
uint64_t UniformBelow64(std::mt19937& rng, uint64_t n) {
  const uint64_t high = rng();
  const uint64_t x = (high << 32) | rng();
  return static_cast<uint64_t>((static_cast<unsigned __int128>(x) * n) >> 64);
}

// Index of the centre nearest to `d` among `count` consecutive centres (ties: the first).
inline int Nearest(const uint8_t* d, const uint8_t* centres, int count) {
  int best = 0;
  int best_distance = DescriptorDistance(d, centres);
  for (int c = 1; c < count; ++c) {
    const int distance = DescriptorDistance(d, centres + c * kBytes);
    if (distance < best_distance) {
      best_distance = distance;
      best = c;
    }
  }
  return best;
}

// k-medians of the descriptors `members` (row indices into `data`): k-means++ seeding (each
// next centre drawn with probability proportional to the squared distance to the nearest
// centre so far, the best of a few draws; fewer than k centres when the members have fewer
// distinct values), then rounds of bitwise-majority update and assignment until nothing moves
// or `iterations` rounds are done. `centres` receives the non-empty clusters' centres (32 bytes
// each, consecutive) and `groups` their members; every member is nearest (first on ties) to its own
// group's centre, so the tree's descent retraces the clustering.
// Greedy k-means++ (as scikit-learn seeds): each step draws a few candidates and keeps the one
// that lowers the total squared distance most. Plain k-means++ now and then draws two centres in
// one natural cluster and none in another, which k-medians cannot undo: that cluster is then
// split between the words of its neighbours. Returns up to k centres (32 bytes each,
// consecutive); fewer when the members have fewer distinct values.
std::vector<uint8_t> SeedCentres(const uint8_t* data, const std::vector<uint32_t>& members, int k,
                                 std::mt19937& rng) {
  const size_t n = members.size();
  auto row = [&](size_t i) { return data + static_cast<size_t>(members[i]) * kBytes; };
  const int trials = 2 + static_cast<int>(std::log(static_cast<double>(k)));
  std::vector<uint8_t> c;
  std::vector<uint64_t> d2(n), candidate_d2(n), best_d2(n);
  const size_t first = UniformBelow(rng, static_cast<uint32_t>(n));
  c.insert(c.end(), row(first), row(first) + kBytes);
  for (size_t j = 0; j < n; ++j) {
    const auto d = static_cast<uint64_t>(DescriptorDistance(row(j), row(first)));
    d2[j] = d * d;
  }
  int count = 1;
  while (count < k) {
    uint64_t total = 0;
    for (uint64_t d : d2) total += d;
    if (total == 0) break;  // every member equals a centre
    size_t best = n;
    uint64_t best_total = 0;
    for (int trial = 0; trial < trials; ++trial) {
      const uint64_t r = UniformBelow64(rng, total);
      uint64_t cumulative = 0;
      size_t pick = 0;
      for (; pick + 1 < n; ++pick) {
        cumulative += d2[pick];
        if (cumulative > r) break;
      }
      uint64_t candidate_total = 0;
      for (size_t j = 0; j < n; ++j) {
        const auto d = static_cast<uint64_t>(DescriptorDistance(row(j), row(pick)));
        candidate_d2[j] = std::min(d2[j], d * d);
        candidate_total += candidate_d2[j];
      }
      if (best == n || candidate_total < best_total) {
        best = pick;
        best_total = candidate_total;
        best_d2.swap(candidate_d2);
      }
    }
    c.insert(c.end(), row(best), row(best) + kBytes);
    d2.swap(best_d2);
    ++count;
  }

  return c;
}

// The median of binary vectors under the Hamming distance, per cluster of `assignment`: each
// bit set where most of its members have it set. An empty cluster keeps its centre.
void UpdateMedians(const uint8_t* data, const std::vector<uint32_t>& members,
                   const std::vector<int>& assignment, int count, std::vector<uint8_t>* c) {
  const size_t n = members.size();
  auto row = [&](size_t i) { return data + static_cast<size_t>(members[i]) * kBytes; };
  std::vector<uint32_t> bits(static_cast<size_t>(count) * 256);
  std::vector<uint32_t> sizes(static_cast<size_t>(count));
  for (size_t i = 0; i < n; ++i) {
    uint32_t* b = bits.data() + static_cast<size_t>(assignment[i]) * 256;
    const uint8_t* d = row(i);
    for (int byte = 0; byte < kBytes; ++byte) {
      for (int bit = 0; bit < 8; ++bit) b[byte * 8 + bit] += (d[byte] >> bit) & 1u;
    }
    ++sizes[static_cast<size_t>(assignment[i])];
  }
  for (int j = 0; j < count; ++j) {
    if (sizes[static_cast<size_t>(j)] == 0) continue;  // keeps its centre
    const uint32_t* b = bits.data() + static_cast<size_t>(j) * 256;
    uint8_t* centre = c->data() + static_cast<size_t>(j) * kBytes;
    for (int byte = 0; byte < kBytes; ++byte) {
      uint8_t value = 0;
      for (int bit = 0; bit < 8; ++bit) {
        if (2 * b[byte * 8 + bit] > sizes[static_cast<size_t>(j)]) value |= 1u << bit;
      }
      centre[byte] = value;
    }
  }
}

void KMedians(const uint8_t* data, const std::vector<uint32_t>& members, int k, int iterations,
              std::mt19937& rng, std::vector<uint8_t>* centres,
              std::vector<std::vector<uint32_t>>* groups) {
  const size_t n = members.size();
  auto row = [&](size_t i) { return data + static_cast<size_t>(members[i]) * kBytes; };

  std::vector<uint8_t> c = SeedCentres(data, members, k, rng);
  const int count = static_cast<int>(c.size() / kBytes);
  std::vector<int> assignment(n, -1);
  auto assign = [&] {
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      const int nearest = Nearest(row(i), c.data(), count);
      changed |= nearest != assignment[i];
      assignment[i] = nearest;
    }
    return changed;
  };
  assign();
  for (int round = 0; round < iterations; ++round) {
    UpdateMedians(data, members, assignment, count, &c);
    if (!assign()) break;
  }

  // Empty clusters are dropped; that changes no member's nearest centre.
  std::vector<std::vector<uint32_t>> g(static_cast<size_t>(count));
  for (size_t i = 0; i < n; ++i) g[static_cast<size_t>(assignment[i])].push_back(members[i]);
  centres->clear();
  groups->clear();
  for (int j = 0; j < count; ++j) {
    if (g[static_cast<size_t>(j)].empty()) continue;
    centres->insert(centres->end(), c.begin() + j * kBytes, c.begin() + (j + 1) * kBytes);
    groups->push_back(std::move(g[static_cast<size_t>(j)]));
  }
}

void CheckDescriptors(const cv::Mat& descriptors, const std::string& what) {
  if (descriptors.empty()) return;
  if (descriptors.type() != CV_8UC1 || descriptors.cols != kBytes) {
    throw Error(
        fmt::format("{}: expected 256-bit binary descriptors (CV_8U, 32 columns), got {} "
                    "columns of type {}",
                    what, descriptors.cols, cv::typeToString(descriptors.type())));
  }
}

// Reads the file format from memory with bounds checks; every failure names the file.
class Reader {
 public:
  Reader(const uint8_t* data, size_t size, const std::string& name)
      : data_(data), size_(size), name_(name) {}
  void Need(size_t bytes, const char* what) const {
    if (size_ - offset_ < bytes) {
      throw Error(fmt::format("{}: truncated vocabulary ({} bytes; {} ends past the end)", name_,
                              size_, what));
    }
  }
  template <typename T>
  T Read(const char* what) {
    Need(sizeof(T), what);
    T value;
    std::memcpy(&value, data_ + offset_, sizeof(T));
    offset_ += sizeof(T);
    return value;
  }
  const uint8_t* Take(size_t bytes, const char* what) {
    Need(bytes, what);
    const uint8_t* p = data_ + offset_;
    offset_ += bytes;
    return p;
  }
  size_t offset() const { return offset_; }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t offset_ = 0;
  const std::string& name_;
};

template <typename T>
void Append(std::string* out, const T& value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

// Every training image's descriptors in one block, rows in image order, checked: at least 2
// images with features and fewer than 2^32 descriptors in all.
std::vector<uint8_t> StackDescriptors(const std::vector<cv::Mat>& descriptor_sets) {
  size_t total = 0;
  int non_empty = 0;
  for (size_t i = 0; i < descriptor_sets.size(); ++i) {
    CheckDescriptors(descriptor_sets[i], fmt::format("training image {}", i));
    total += static_cast<size_t>(descriptor_sets[i].rows);
    non_empty += descriptor_sets[i].rows > 0;
  }
  if (non_empty < 2) {
    throw Error(fmt::format("a vocabulary needs at least 2 training images with features; got {}",
                            non_empty));
  }
  if (total >= UINT32_MAX) throw Error("too many training descriptors (at most 2^32 - 1)");

  std::vector<uint8_t> data(total * kBytes);
  {
    size_t offset = 0;
    for (const cv::Mat& set : descriptor_sets) {
      for (int r = 0; r < set.rows; ++r, offset += kBytes)
        std::memcpy(data.data() + offset, set.ptr<uint8_t>(r), kBytes);
    }
  }

  return data;
}

// IDF per word of `v`: the log of the training images over those in which the word occurs.
std::vector<double> IdfWeights(const Vocabulary& v, const std::vector<cv::Mat>& descriptor_sets,
                               const std::vector<uint8_t>& data) {
  std::vector<double> weights(v.size(), 0.0);
  // In how many training images each word occurs.
  std::vector<uint32_t> images_with(v.size(), 0);
  std::vector<uint32_t> last_image(v.size(), UINT32_MAX);
  {
    size_t offset = 0;
    for (size_t i = 0; i < descriptor_sets.size(); ++i) {
      for (int r = 0; r < descriptor_sets[i].rows; ++r, offset += kBytes) {
        const WordId w = v.WordOf(data.data() + offset);
        if (last_image[w] != i) {
          last_image[w] = static_cast<uint32_t>(i);
          ++images_with[w];
        }
      }
    }
  }
  const double images = static_cast<double>(descriptor_sets.size());
  for (size_t w = 0; w < v.size(); ++w) {
    // Every leaf holds a training descriptor, so the count is at least 1.
    weights[w] = std::log(images / std::max<uint32_t>(images_with[w], 1));
  }
  return weights;
}

}  // namespace

void VocabularyOptions::Check() const {
  if (branching < 2 || branching > 255) throw Error("vocabulary branching must be in 2..255");
  if (depth < 1 || depth > 10) throw Error("vocabulary depth must be in 1..10");
  if (std::pow(static_cast<double>(branching), depth) > 1e8) {
    throw Error(
        fmt::format("vocabulary of branching {} and depth {} would have {:.3g} words; at "
                    "most 1e8",
                    branching, depth, std::pow(static_cast<double>(branching), depth)));
  }
  if (kmeans_iterations < 1 || kmeans_iterations > 1000)
    throw Error("vocabulary k-means iterations must be in 1..1000");
}

Vocabulary Vocabulary::Train(const std::vector<cv::Mat>& descriptor_sets,
                             const VocabularyOptions& options) {
  options.Check();
  const std::vector<uint8_t> data = StackDescriptors(descriptor_sets);
  const size_t total = data.size() / kBytes;

  Vocabulary v;
  v.branching_ = options.branching;
  v.depth_ = options.depth;
  v.training_images_ = static_cast<uint32_t>(descriptor_sets.size());
  v.training_descriptors_ = total;
  v.centres_.assign(kBytes, 0);  // the root's, unused
  v.child_count_.push_back(0);

  // Breadth-first: a node's children are appended together when it is split, so they are
  // consecutive, and nodes are split in the order of their ids.
  struct Pending {
    uint32_t node;
    int level;
    std::vector<uint32_t> members;
  };
  std::deque<Pending> queue;
  {
    std::vector<uint32_t> all(total);
    for (size_t i = 0; i < total; ++i) all[i] = static_cast<uint32_t>(i);
    queue.push_back({0, 0, std::move(all)});
  }
  std::mt19937 rng(options.seed);
  std::vector<uint8_t> centres;
  std::vector<std::vector<uint32_t>> groups;
  while (!queue.empty()) {
    Pending p = std::move(queue.front());
    queue.pop_front();
    if (p.level >= options.depth || p.members.size() <= 1) continue;  // a leaf
    KMedians(data.data(), p.members, options.branching, options.kmeans_iterations, rng, &centres,
             &groups);
    if (groups.size() < 2) continue;  // all members alike: a leaf
    v.child_count_[p.node] = static_cast<uint8_t>(groups.size());
    for (size_t g = 0; g < groups.size(); ++g) {
      const auto id = static_cast<uint32_t>(v.child_count_.size());
      v.child_count_.push_back(0);
      v.centres_.insert(v.centres_.end(), centres.begin() + static_cast<long>(g) * kBytes,
                        centres.begin() + static_cast<long>(g + 1) * kBytes);
      queue.push_back({id, p.level + 1, std::move(groups[g])});
    }
  }
  v.Index();
  v.weights_.assign(v.word_count_, 0.0);

  v.weights_ = IdfWeights(v, descriptor_sets, data);
  return v;
}

void Vocabulary::Index() {
  const size_t n = child_count_.size();
  first_child_.assign(n, 0);
  word_.assign(n, kNoWord);
  uint32_t next = 1;
  WordId words = 0;
  for (size_t i = 0; i < n; ++i) {
    if (child_count_[i] == 0) {
      word_[i] = words++;
    } else {
      first_child_[i] = next;
      next += child_count_[i];
    }
  }
  word_count_ = words;
}

WordId Vocabulary::WordOf(const uint8_t* descriptor) const {
  uint32_t node = 0;
  while (child_count_[node] != 0) {
    node = first_child_[node] +
           Nearest(descriptor, centres_.data() + static_cast<size_t>(first_child_[node]) * kBytes,
                   child_count_[node]);
  }
  return word_[node];
}

void Vocabulary::Transform(const cv::Mat& descriptors, BowVector* bow, FeatureVector* features,
                           int levels_up) const {
  if (size() == 0) throw Error("Transform on an empty vocabulary (neither trained nor loaded)");
  CheckDescriptors(descriptors, "Vocabulary::Transform");
  if (levels_up < 0) throw Error("Vocabulary::Transform: levels_up must be >= 0");
  bow->clear();
  if (features != nullptr) features->clear();
  const int target_level = std::max(0, depth_ - levels_up);

  // Collected in vectors and sorted, then written to the maps in order: cheaper than a map
  // insertion per descriptor.
  std::vector<std::pair<WordId, double>> words;
  std::vector<std::pair<uint32_t, int>> nodes;
  words.reserve(static_cast<size_t>(descriptors.rows));
  if (features != nullptr) nodes.reserve(static_cast<size_t>(descriptors.rows));
  for (int r = 0; r < descriptors.rows; ++r) {
    const uint8_t* d = descriptors.ptr<uint8_t>(r);
    uint32_t node = 0;
    uint32_t feature_node = 0;  // the root, for target level 0
    int level = 0;
    while (child_count_[node] != 0) {
      const uint32_t first = first_child_[node];
      node = first +
             static_cast<uint32_t>(Nearest(d, centres_.data() + static_cast<size_t>(first) * kBytes,
                                           child_count_[node]));
      if (++level == target_level) feature_node = node;
    }
    const WordId w = word_[node];
    if (weights_[w] > 0) words.emplace_back(w, weights_[w]);
    if (features != nullptr) nodes.emplace_back(level < target_level ? node : feature_node, r);
  }

  std::sort(words.begin(), words.end());
  double sum = 0;
  for (const auto& [w, weight] : words) sum += weight;
  for (const auto& [w, weight] : words) {
    auto it = bow->end();
    if (!bow->empty() && std::prev(it)->first == w) {
      std::prev(it)->second += weight / sum;
    } else {
      bow->emplace_hint(it, w, weight / sum);
    }
  }
  if (features != nullptr) {
    std::sort(nodes.begin(), nodes.end());  // by node, then feature index
    for (const auto& [node, r] : nodes) {
      auto it = features->end();
      if (features->empty() || std::prev(it)->first != node)
        it = features->emplace_hint(it, node, std::vector<int>{});
      else
        it = std::prev(it);
      it->second.push_back(r);
    }
  }
}

double Vocabulary::Score(const BowVector& a, const BowVector& b) {
  double sa = 0, sb = 0;
  for (const auto& [w, x] : a) sa += std::abs(x);
  for (const auto& [w, x] : b) sb += std::abs(x);
  if (sa <= 0 || sb <= 0) return 0.0;
  // For L1-normalised a and b, |x - y| = x + y - 2 min(x, y) gives
  // 1 - 0.5 |a - b|_1 = sum over the words both have of min(a_w, b_w): the words only one of
  // them has need not be visited.
  double common = 0;
  auto ia = a.begin(), ib = b.begin();
  while (ia != a.end() && ib != b.end()) {
    if (ia->first < ib->first) {
      ++ia;
    } else if (ib->first < ia->first) {
      ++ib;
    } else {
      common += std::min(std::abs(ia->second) / sa, std::abs(ib->second) / sb);
      ++ia;
      ++ib;
    }
  }
  return std::clamp(common, 0.0, 1.0);
}

std::string Vocabulary::ToBytes() const {
  std::string out;
  out.reserve(64 + child_count_.size() * (1 + kBytes) + weights_.size() * 8);
  out.append(kMagic, sizeof(kMagic));
  Append(&out, kVersion);
  Append(&out, static_cast<uint32_t>(branching_));
  Append(&out, static_cast<uint32_t>(depth_));
  Append(&out, static_cast<uint32_t>(child_count_.size()));
  Append(&out, static_cast<uint32_t>(weights_.size()));
  Append(&out, training_images_);
  Append(&out, training_descriptors_);
  out.append(reinterpret_cast<const char*>(child_count_.data()), child_count_.size());
  out.append(reinterpret_cast<const char*>(centres_.data()), centres_.size());
  out.append(reinterpret_cast<const char*>(weights_.data()), weights_.size() * sizeof(double));
  Append(&out, Fnv1a(reinterpret_cast<const uint8_t*>(out.data()), out.size()));
  return out;
}

void Vocabulary::Save(const std::string& path) const {
  if (size() == 0) throw Error("cannot save an empty vocabulary to " + path);
  const std::string bytes = ToBytes();
  if (bytes.size() > kMaxVocabularyBytes) {
    throw Error(
        fmt::format("{}: a vocabulary of {} words is {} bytes, more than the {} a "
                    "vocabulary file may have; use a smaller depth or branching",
                    path, size(), bytes.size(), kMaxVocabularyBytes));
  }
  WriteFileAtomically(path, [&](std::ostream& out) { out.write(bytes.data(), bytes.size()); });
}

Vocabulary Vocabulary::Load(const std::string& path) {
  const std::optional<std::string> bytes = ReadRegularFileIfExists(path, kMaxVocabularyBytes);
  if (!bytes) throw Error("file not found: " + path);
  return FromBytes(bytes->data(), bytes->size(), path);
}

Vocabulary Vocabulary::FromBytes(const void* data, size_t size, const std::string& name) {
  const auto* bytes = static_cast<const uint8_t*>(data);
  Reader reader(bytes, size, name);
  if (size < sizeof(kMagic) || std::memcmp(bytes, kMagic, sizeof(kMagic)) != 0)
    throw Error(name + ": not an sdoslam vocabulary (bad magic)");
  reader.Take(sizeof(kMagic), "magic");
  const auto version = reader.Read<uint32_t>("the header");
  if (version != kVersion) {
    throw Error(fmt::format("{}: vocabulary format version {}; this build reads version {}", name,
                            version, kVersion));
  }
  Vocabulary v;
  const auto branching = reader.Read<uint32_t>("the header");
  const auto depth = reader.Read<uint32_t>("the header");
  const auto nodes = reader.Read<uint32_t>("the header");
  const auto words = reader.Read<uint32_t>("the header");
  v.training_images_ = reader.Read<uint32_t>("the header");
  v.training_descriptors_ = reader.Read<uint64_t>("the header");
  VocabularyOptions options;
  options.branching = static_cast<int>(std::min<uint32_t>(branching, 1000));
  options.depth = static_cast<int>(std::min<uint32_t>(depth, 1000));
  try {
    options.Check();
  } catch (const Error& e) {
    throw Error(name + ": corrupt vocabulary: " + e.what());
  }
  if (nodes == 0 || words == 0 || words > nodes)
    throw Error(fmt::format("{}: corrupt vocabulary ({} nodes, {} words)", name, nodes, words));
  v.branching_ = options.branching;
  v.depth_ = options.depth;
  const uint8_t* counts = reader.Take(nodes, "the tree");
  const uint8_t* centres = reader.Take(static_cast<size_t>(nodes) * kBytes, "the node centres");
  const uint8_t* weights = reader.Take(static_cast<size_t>(words) * sizeof(double), "the weights");
  const size_t checked = reader.offset();
  const auto checksum = reader.Read<uint64_t>("the checksum");
  if (reader.offset() != size) {
    throw Error(fmt::format("{}: corrupt vocabulary ({} bytes after the checksum)", name,
                            size - reader.offset()));
  }
  if (checksum != Fnv1a(bytes, checked))
    throw Error(name + ": corrupt vocabulary (checksum mismatch)");

  v.child_count_.assign(counts, counts + nodes);
  v.centres_.assign(centres, centres + static_cast<size_t>(nodes) * kBytes);
  v.weights_.resize(words);
  std::memcpy(v.weights_.data(), weights, static_cast<size_t>(words) * sizeof(double));
  v.Index();
  // The tree must be one the descent can walk: children after their parent, every node
  // reached once, no deeper than `depth`, as many leaves as words, finite weights.
  std::vector<uint8_t> level(nodes, 0);
  uint64_t children = 0;
  size_t leaves = 0;
  for (uint32_t i = 0; i < nodes; ++i) {
    if (v.child_count_[i] == 0) {
      ++leaves;
      continue;
    }
    children += v.child_count_[i];
    if (v.child_count_[i] > branching || v.first_child_[i] <= i ||
        v.first_child_[i] + v.child_count_[i] > nodes || level[i] >= depth) {
      throw Error(fmt::format("{}: corrupt vocabulary (node {})", name, i));
    }
    for (uint32_t c = 0; c < v.child_count_[i]; ++c)
      level[v.first_child_[i] + c] = static_cast<uint8_t>(level[i] + 1);
  }
  if (children + 1 != nodes || leaves != words || v.word_count_ != words)
    throw Error(fmt::format("{}: corrupt vocabulary (tree does not add up)", name));
  for (double w : v.weights_) {
    if (!std::isfinite(w) || w < 0) throw Error(name + ": corrupt vocabulary (weights)");
  }
  return v;
}

}  // namespace sdoslam
