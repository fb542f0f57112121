#include "sdoslam/apps/vocab_command.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "sdoslam/core/error.h"
#include "sdoslam/features/orb_extractor.h"
#include "sdoslam/io/png_reader.h"
#include "sdoslam/place/default_vocabulary.h"
#include "sdoslam/place/vocabulary.h"

namespace sdoslam {
namespace {

namespace fs = std::filesystem;

struct VocabArgs {
  std::vector<std::string> images;
  std::string out;
  VocabularyOptions options;
  int max_images = 0;
  std::string file;  // info
};

bool IsImage(const fs::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return extension == ".png" || extension == ".jpg" || extension == ".jpeg";
}

std::vector<fs::path> ImagesIn(const fs::path& folder) {
  std::vector<fs::path> images;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (entry.is_regular_file() && IsImage(entry.path())) images.push_back(entry.path());
  }
  std::sort(images.begin(), images.end());
  return images;
}

// The images of each folder, sorted by name; a folder without images of its own but with an
// rgb/ (a TUM sequence) gives those of rgb/.
std::vector<fs::path> CollectImages(const std::vector<std::string>& folders) {
  std::vector<fs::path> all;
  for (const std::string& folder : folders) {
    if (!fs::is_directory(folder)) throw Error("image folder not found: " + folder);
    std::vector<fs::path> images = ImagesIn(folder);
    if (images.empty() && fs::is_directory(fs::path(folder) / "rgb"))
      images = ImagesIn(fs::path(folder) / "rgb");
    if (images.empty()) throw Error(folder + ": no .png or .jpg images (nor in its rgb/)");
    all.insert(all.end(), images.begin(), images.end());
  }
  return all;
}

void Build(const VocabArgs& args) {
  args.options.Check();
  const auto start = std::chrono::steady_clock::now();
  std::vector<fs::path> images = CollectImages(args.images);
  if (args.max_images > 0 && static_cast<int>(images.size()) > args.max_images) {
    // Spread over the whole list: consecutive video frames add little to each other.
    std::vector<fs::path> kept;
    for (int i = 0; i < args.max_images; ++i)
      kept.push_back(images[static_cast<size_t>(i) * images.size() / args.max_images]);
    images = std::move(kept);
  }
  // ORB exactly as runs extract it: default options, on the grey image of the colour image.
  const OrbExtractor orb(OrbOptions{});
  std::vector<cv::Mat> descriptors(images.size());
  std::vector<std::string> unreadable(images.size());  // the message, per image
  tbb::parallel_for(size_t{0}, images.size(), [&](size_t i) {
    cv::Mat bgr;
    try {
      bgr = ReadImage(images[i], cv::IMREAD_COLOR);
    } catch (const Error& e) {  // not a regular file: said once the workers are done
      unreadable[i] = e.what();
      return;
    }
    if (bgr.empty()) {
      unreadable[i] = "cannot read image " + images[i].string();
      return;
    }
    cv::Mat gray;
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
    std::vector<cv::KeyPoint> keypoints;
    orb.Extract(gray, &keypoints, &descriptors[i]);
  });
  for (const std::string& message : unreadable) {
    if (!message.empty()) throw Error(message);
  }
  size_t total = 0;
  for (const cv::Mat& d : descriptors) total += static_cast<size_t>(d.rows);
  const double extract_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const Vocabulary vocabulary = Vocabulary::Train(descriptors, args.options);
  vocabulary.Save(args.out);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << fmt::format(
      "vocabulary of {} words (branching {}, depth {}) from {} images, {} descriptors, in "
      "{:.1f} s (features {:.1f} s, training {:.1f} s) -> {}\n",
      vocabulary.size(), vocabulary.branching(), vocabulary.depth(), images.size(), total, seconds,
      extract_seconds, seconds - extract_seconds, args.out);
}

void Info(const VocabArgs& args) {
  const Vocabulary vocabulary =
      args.file.empty() ? DefaultVocabulary() : Vocabulary::Load(args.file);
  const size_t bytes =
      args.file.empty() ? DefaultVocabularyBytes().size() : fs::file_size(args.file);
  std::cout << fmt::format(
      "{}: {} words, branching {}, depth {}, {} nodes, {} bytes; trained on {} images, {} "
      "descriptors\n",
      args.file.empty() ? "built-in vocabulary" : args.file, vocabulary.size(),
      vocabulary.branching(), vocabulary.depth(), vocabulary.nodes(), bytes,
      vocabulary.training_images(), vocabulary.training_descriptors());
}

}  // namespace

void AddVocabCommand(CLI::App& app) {
  auto args = std::make_shared<VocabArgs>();
  CLI::App* vocab =
      app.add_subcommand("vocab", "place-recognition vocabularies (bags of binary words)");
  vocab->require_subcommand(1);

  CLI::App* build =
      vocab->add_subcommand("build", "train a vocabulary on the ORB features of a set of images");
  build
      ->add_option("--images", args->images,
                   "folders of .png/.jpg images, read in name order (a TUM sequence's folder "
                   "reads its rgb/)")
      ->required()
      ->expected(1, -1);
  build->add_option("--out", args->out, "vocabulary file to write")->required();
  build->add_option("--branching", args->options.branching, "children per node")
      ->capture_default_str();
  build->add_option("--depth", args->options.depth, "levels: at most branching^depth words")
      ->capture_default_str();
  build->add_option("--seed", args->options.seed, "seed of the clustering")->capture_default_str();
  build
      ->add_option("--max-images", args->max_images,
                   "use at most this many images, spread evenly over all (0: all)")
      ->check(CLI::NonNegativeNumber);
  build->callback([args] { Build(*args); });

  CLI::App* info =
      vocab->add_subcommand("info", "describe a vocabulary file (default: the built-in one)");
  info->add_option("file", args->file, "vocabulary file");
  info->callback([args] { Info(*args); });
}

}  // namespace sdoslam
