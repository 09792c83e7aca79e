// retrace bench kidnap: relocalization at scale (issue 16). A robot is set down at random places of a repeat drive
// with no start arc and a fresh localizer (a kidnapped start); each start runs --frames frames from there. Scored
// against topological ground truth (KITTI poses of the teach sequence the map names and of this sequence, as
// `repeat --evaluate`): a start is localized at frame k when frame k is reported `tracking` on the true arc (or the
// one tolerated near a node, evaluation.h); a frame reported `tracking` on any other arc is wrong. Times are the
// localizer's own per-frame wall time (FrameResult::seconds, one thread). With --lost-sequence, one localizer is
// fed frames of another drive (a place not in the map: it stays lost) and the relocalizing frames' times are
// reported: what a lost robot pays per frame (its verification budget, LocalizerOptions::retrieval_shortlist, not the
// start's).
//
//   retrace bench kidnap --map big.db --sequence drive_repeat --starts 100 --frames 3 [--lost-sequence other]
//
// retrace bench retrieval: for every frame of a drive (or every --every-th), the rank of its true arc's key-images
// (recall@1, @5, @20) by the float thumbnails of before issue 16, by the quantised index of their appearance, by
// visual words and by both fused (what the localizer ranks the whole map by).

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numeric>
#include <random>

#include <time.h>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/feature/binary_features.h"
#include "retrace/feature/global_descriptor.h"
#include "retrace/feature/visual_words.h"
#include "retrace/exe/commands.h"
#include "retrace/image/image_utils.h"
#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/localizer.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/util/error.h"
#include "retrace/util/memory_usage.h"

namespace retrace {
namespace {

struct KidnapArguments {
  std::filesystem::path map;
  std::filesystem::path sequence;
  std::filesystem::path lost_sequence;
  std::filesystem::path output;
  int starts = 100;
  int frames = 3;
  int lost_frames = 60;
  unsigned seed = 1;
  std::vector<size_t> at;  // explicit start frames instead of random ones
  LocalizerOptions options;
};

// CPU time of this process (all threads), seconds: with one thread (cv::setNumThreads(1)) the frame's own work, free
// of the waiting a loaded machine adds to wall time.
double ProcessCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  const size_t index = std::min(values.size() - 1, static_cast<size_t>(std::ceil(p * values.size())) - (p > 0 ? 1 : 0));
  return values[index];
}

// Frame `index` of `sequence` at the camera's width (as `retrace repeat` resizes frames of the map camera's shape).
Frame ReadFrame(Sequence& sequence, size_t index, const CameraModel& camera) {
  Frame frame;
  if (!sequence.Read(index, &frame)) {
    throw InputError(sequence.path().string(), fmt::format("frame {} cannot be read", index));
  }
  if (frame.image.cols != camera.width()) {
    cv::Mat resized;
    ResizeToWidth(frame.image, camera.width(), &resized);
    frame.image = resized;
  }
  if (frame.image.rows != camera.height()) {
    throw InputError(sequence.path().string(), fmt::format("frames are {}x{} at the map's width, the map's camera {}x{}",
                                                           frame.image.cols, frame.image.rows, camera.width(),
                                                           camera.height()));
  }
  return frame;
}

std::vector<TimedPose> TruthOf(const std::filesystem::path& sequence_path) {
  const auto file = OpenSequence(sequence_path)->ground_truth_file();
  if (!file || file->filename() != "poses.txt") {
    throw InputError(sequence_path.string(), "needs KITTI ground-truth poses (poses.txt)");
  }
  return ReadKittiPoses(*file);
}

// A map and a drive to run against it, with the ground truth of both (the teach sequence the map names).
struct BenchDrive {
  MapForLocalizer loaded;
  std::vector<TimedPose> key_truth, repeat_truth;
  std::unique_ptr<Sequence> sequence;
};

BenchDrive LoadBenchDrive(const std::filesystem::path& map, const std::filesystem::path& sequence,
                          const LocalizerOptions& options) {
  BenchDrive drive{LoadMapForLocalizer(map, options), {}, {}, nullptr};
  if (!drive.loaded.camera) throw InputError(map.string(), "the map stores no camera");
  if (!drive.loaded.source_sequence) throw InputError(map.string(), "the map does not name its teach sequence");
  drive.key_truth = TruthOf(*drive.loaded.source_sequence);
  drive.repeat_truth = TruthOf(sequence);
  drive.sequence = OpenSequence(sequence);
  return drive;
}

void RunKidnap(const KidnapArguments& args) {
  cv::setNumThreads(1);  // the figures are for one thread
  BenchDrive drive = LoadBenchDrive(args.map, args.sequence, args.options);
  MapForLocalizer& loaded = drive.loaded;
  const std::vector<TimedPose>& key_truth = drive.key_truth;
  const std::vector<TimedPose>& repeat_truth = drive.repeat_truth;
  std::unique_ptr<Sequence>& sequence = drive.sequence;
  const size_t n = sequence->size();
  if (n < static_cast<size_t>(args.frames)) throw InputError(args.sequence.string(), "fewer frames than --frames");

  // The truth of every frame from the whole drive (its order along the route): a kidnapped start's few frames
  // evaluated alone were judged against the other pass where a route crosses itself (the last frames of the
  // validation matrix's mixed134 and mixed142, reported on their true arcs, counted wrong).
  std::vector<RepeatRecord> all_frames;
  for (size_t i = 0; i < n; ++i) all_frames.push_back({i, false, kInvalidArcId});
  const TopologicalEvaluation truth = EvaluateTopological(loaded.map, key_truth, repeat_truth, all_frames);
  const std::vector<arc_t> route = RouteArcs(loaded.map);

  std::mt19937 rng(args.seed);
  std::uniform_int_distribution<size_t> pick(0, n - args.frames);
  std::ofstream csv;
  if (!args.output.empty()) {
    csv.open(args.output);
    if (!csv) throw InputError(args.output.string(), "cannot be written");
    csv << "start,frame,state,arc,correct,wrong,ms,key_images_matched,confidence\n";
  }
  int at_first = 0, within = 0, wrong_frames = 0, wrong_starts = 0;
  std::vector<double> first_ms, first_cpu_ms, unlocalized_ms;
  const int starts = args.at.empty() ? args.starts : static_cast<int>(args.at.size());
  for (int s = 0; s < starts; ++s) {
    const size_t start = args.at.empty() ? pick(rng) : args.at[s];
    if (start + args.frames > n) throw InputError(args.sequence.string(), fmt::format("no frames {}+", start));
    Localizer localizer(loaded.map, *loaded.camera, loaded.options);
    std::vector<FrameResult> results;
    for (int k = 0; k < args.frames; ++k) {
      const Frame frame = ReadFrame(*sequence, start + k, *loaded.camera);
      const double cpu_start = ProcessCpuSeconds();
      results.push_back(localizer.ProcessFrame(frame));
      if (k == 0) first_cpu_ms.push_back(1000.0 * (ProcessCpuSeconds() - cpu_start));
    }
    bool localized = false, wrong = false;
    for (int k = 0; k < args.frames; ++k) {
      const bool tracking = results[k].state == LocalizerState::kTracking;
      const bool correct = tracking && IsCorrectEstimate(truth.per_frame[start + k], route, results[k].arc);
      const bool frame_wrong = tracking && !correct;
      wrong_frames += frame_wrong;
      wrong |= frame_wrong;
      if (k == 0) {
        first_ms.push_back(1000.0 * results[k].seconds);
        at_first += correct;
      }
      localized |= correct;
      if (results[k].state != LocalizerState::kTracking) unlocalized_ms.push_back(1000.0 * results[k].seconds);
      if (csv.is_open()) {
        csv << fmt::format("{},{},{},{},{:d},{:d},{:.2f},{},{:.4f}\n", start, start + k,
                           LocalizerStateName(results[k].state), results[k].arc, correct, frame_wrong,
                           1000.0 * results[k].seconds, results[k].key_images_matched, results[k].confidence);
      }
    }
    within += localized;
    wrong_starts += wrong;
  }
  std::cout << fmt::format(
      "kidnap: {} starts on a map of {} key-images ({} arcs), {} frames each: localized at the first frame {} "
      "({:.1f} %), within {} frames {} ({:.1f} %); {} wrong frames in {} starts\n",
      starts, loaded.map.nodes().size(), loaded.map.arcs().size(), args.frames, at_first,
      100.0 * at_first / starts, args.frames, within, 100.0 * within / starts, wrong_frames, wrong_starts);
  std::cout << fmt::format("kidnap: first frame {:.1f} ms median, {:.1f} ms 95th percentile, {:.1f} ms max (wall); "
                           "CPU {:.1f} ms median, {:.1f} ms 95th percentile; frames not localized: {} ({:.1f} ms "
                           "median)\n",
                           Percentile(first_ms, 0.5), Percentile(first_ms, 0.95), Percentile(first_ms, 1.0),
                           Percentile(first_cpu_ms, 0.5), Percentile(first_cpu_ms, 0.95), unlocalized_ms.size(),
                           Percentile(unlocalized_ms, 0.5));

  if (!args.lost_sequence.empty()) {
    std::unique_ptr<Sequence> lost = OpenSequence(args.lost_sequence);
    // A robot lost after it was localized verifies retrieval_shortlist candidates per frame; a fresh localizer, which
    // has never been localized, stands in for it with the start's larger budget set to that.
    LocalizerOptions lost_options = loaded.options;
    lost_options.start_retrieval_shortlist = lost_options.retrieval_shortlist;
    Localizer localizer(loaded.map, *loaded.camera, lost_options);
    std::vector<double> ms, cpu_ms;
    int tracking = 0;
    const size_t count = std::min(lost->size(), static_cast<size_t>(args.lost_frames));
    for (size_t i = 0; i < count; ++i) {
      const Frame frame = ReadFrame(*lost, i, *loaded.camera);
      const double cpu_start = ProcessCpuSeconds();
      const FrameResult result = localizer.ProcessFrame(frame);
      if (result.state == LocalizerState::kTracking) {
        ++tracking;
      } else {
        ms.push_back(1000.0 * result.seconds);
        cpu_ms.push_back(1000.0 * (ProcessCpuSeconds() - cpu_start));
      }
    }
    std::cout << fmt::format("kidnap: lost in {} ({} frames of a drive elsewhere): {} relocalizing frames, {:.1f} ms "
                             "median, {:.1f} ms 95th percentile (wall; CPU {:.1f} ms median); {} frames reported "
                             "tracking\n",
                             args.lost_sequence.string(), count, ms.size(), Percentile(ms, 0.5),
                             Percentile(ms, 0.95), Percentile(cpu_ms, 0.5), tracking);
  }
  std::cout << fmt::format("kidnap: peak memory {:.0f} MB\n", PeakResidentBytes() / 1e6);
}

struct RetrievalArguments {
  std::filesystem::path map;
  std::filesystem::path sequence;
  size_t every = 1;
  LocalizerOptions options;
};

// Retrieval quality: for every frame of the drive, the rank of the first key-image of its true arc (either end)
// among all key-images, by the float thumbnails (RankByGlobalDescriptor), by the quantised index the localizer used
// (AppearanceIndex over the signatures stored in the map), by visual words (VisualWordIndex over the signatures'
// binary descriptors) and by both fused.
void RunRetrieval(const RetrievalArguments& args) {
  BenchDrive drive = LoadBenchDrive(args.map, args.sequence, args.options);
  MapForLocalizer& loaded = drive.loaded;
  std::unique_ptr<Sequence>& sequence = drive.sequence;
  const Map& map = loaded.map;
  const GlobalDescriptorOptions& options = loaded.options.retrieval;
  std::vector<GlobalDescriptor> thumbnails;
  AppearanceIndex index(options);
  std::vector<size_t> all;
  for (const MapNode& node : map.nodes()) {
    thumbnails.push_back(ComputeGlobalDescriptor(map.KeyImage(node.id), options));
    all.push_back(index.Add(node.signature.appearance));
  }
  // The visual words LoadMapForLocalizer built (entry i the i-th node, as `all`), and the frame's key-points as the
  // localizer extracts them.
  if (!map.visual_words()) throw InputError(args.map.string(), "no stored binary descriptors for visual words");
  const VisualVocabulary& vocabulary = map.visual_words()->vocabulary;
  const VisualWordIndex& words = map.visual_words()->index;
  std::cout << fmt::format("vocabulary: {} words\n", vocabulary.size());
  BinaryFeatureOptions frame_features = loaded.options.relocalization_features;
  frame_features.max_keypoints = loaded.options.relocalization_frame_keypoints;
  frame_features.scale_with_area = true;
  std::vector<Frame> frames;
  std::vector<RepeatRecord> records;
  for (size_t i = 0; i < sequence->size(); i += args.every) {
    frames.push_back(ReadFrame(*sequence, i, *loaded.camera));
    records.push_back({frames.back().source_index, false, kInvalidArcId});
  }
  const TopologicalEvaluation truth = EvaluateTopological(map, drive.key_truth, drive.repeat_truth, records);
  const std::vector<arc_t> route = RouteArcs(map);
  constexpr int kMethods = 4;
  const std::array<const char*, kMethods> names = {"float thumbnails", "quantised index", "visual words",
                                                   "index + words"};
  int queries = 0;
  std::array<int, kMethods> at1{}, at5{}, at20{};
  std::array<double, kMethods> seconds{};
  for (size_t q = 0; q < frames.size(); ++q) {
    const int arc_index = truth.per_frame[q].true_arc_index;
    if (arc_index < 0) continue;
    const Frame& frame = frames[q];
    const MapArc* arc = map.FindArc(route[arc_index]);
    ++queries;
    std::array<std::vector<size_t>, kMethods> orders;
    for (int method = 0; method < kMethods; ++method) {
      const auto start = std::chrono::steady_clock::now();
      if (method <= 1) {
        const GlobalDescriptor query = ComputeGlobalDescriptor(frame.image, options);
        orders[method] = method == 0 ? RankByGlobalDescriptor(query, thumbnails, options)
                                     : index.Rank(QuantizeGlobalDescriptor(query), all);
      } else if (method == 2) {
        const WideBaselineFeatures features = ExtractBinaryFeatures(frame.image, frame_features);
        orders[method] = words.Rank(vocabulary.Words(features.descriptors), all);
      } else {
        orders[method] = FuseRankings(orders[1], orders[2]);
      }
      seconds[method] += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      const std::vector<size_t>& order = orders[method];
      size_t rank = 0;
      while (rank < order.size() && map.nodes()[order[rank]].id != arc->from && map.nodes()[order[rank]].id != arc->to) {
        ++rank;
      }
      at1[method] += rank < 1;
      at5[method] += rank < 5;
      at20[method] += rank < 20;
    }
  }
  if (queries == 0) throw InputError(args.sequence.string(), "no frame has a true arc");
  for (int method = 0; method < kMethods; ++method) {
    std::cout << fmt::format("retrieval ({}): {} frames, {} key-images: recall@1 {:.1f} %, recall@5 {:.1f} %, "
                             "recall@20 {:.1f} %, {:.2f} ms per query\n",
                             names[method], queries, map.nodes().size(), 100.0 * at1[method] / queries,
                             100.0 * at5[method] / queries, 100.0 * at20[method] / queries,
                             1000.0 * seconds[method] / queries);
  }
}

}  // namespace

void RegisterBenchCommand(CLI::App& app) {
  CLI::App* bench = app.add_subcommand("bench", "Measurements against ground truth: relocalization at scale, retrieval, planar heading");
  bench->require_subcommand(1);
  auto args = std::make_shared<KidnapArguments>();
  CLI::App* cmd = bench->add_subcommand(
      "kidnap", "Kidnapped starts: fresh localizers at random frames of a drive, scored against ground truth");
  cmd->add_option("--map", args->map, "Map file written by `retrace teach`")->required();
  cmd->add_option("--sequence", args->sequence, "Drive with KITTI poses.txt (e.g. `sim render --variant repeat`)")
      ->required();
  cmd->add_option("--starts", args->starts, "Kidnapped starts")->check(CLI::Range(1, 100000))->capture_default_str();
  cmd->add_option("--frames", args->frames, "Frames run from each start")->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed of the random start frames")->capture_default_str();
  cmd->add_option("--at", args->at, "Start at these frames instead of random ones");
  cmd->add_option("--output", args->output, "CSV file, one row per frame run");
  cmd->add_option("--lost-sequence", args->lost_sequence,
                  "A drive of a place not in the map: the time of relocalizing frames while lost");
  cmd->add_option("--lost-frames", args->lost_frames, "Frames of --lost-sequence")->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--retrieval-shortlist", args->options.retrieval_shortlist,
                  "Verification budget: key-images verified at most per relocalizing frame (0: all)")
      ->capture_default_str();
  cmd->add_option("--start-retrieval-shortlist", args->options.start_retrieval_shortlist,
                  "Verification budget of the frames before the first localization (0: all)")
      ->capture_default_str();
  // Settings of the relocalization, for measuring alternatives (signatures made with other settings than the map's
  // are computed when the map is loaded).
  cmd->add_option("--keypoints", args->options.relocalization_features.max_keypoints,
                  "Binary key-points per 320x240 image")->capture_default_str();
  cmd->add_option("--frame-keypoints", args->options.relocalization_frame_keypoints,
                  "Binary key-points per 320x240 relocalizing frame")->capture_default_str();
  cmd->add_option("--fast-threshold", args->options.relocalization_features.fast_threshold, "FAST threshold")
      ->capture_default_str();
  cmd->add_option("--patch-size", args->options.relocalization_features.patch_size, "ORB patch size")
      ->capture_default_str();
  cmd->add_option("--ratio", args->options.relocalization_features.ratio, "Ratio test of binary matches")
      ->capture_default_str();
  cmd->add_option("--descriptor-bytes", args->options.relocalization_features.descriptor_bytes,
                  "Bytes kept of each binary descriptor (8, 16, 24 or 32)")
      ->capture_default_str();
  cmd->add_option("--min-inliers", args->options.min_binary_inliers, "Fewest verified inliers (binary)")
      ->capture_default_str();
  cmd->add_option("--ambiguity-ratio", args->options.retrieval_ambiguity_ratio,
                  "A look-alike elsewhere verified with this fraction of the best's inliers: not localized")
      ->capture_default_str();
  cmd->add_option("--global-agreeing-key-images", args->options.min_global_agreeing_key_images,
                  "A relocalization over the whole map needs this many key-images of the chosen arc and its "
                  "neighbours verified")
      ->capture_default_str();
  cmd->add_option("--global-gate-candidates", args->options.global_gate_candidates,
                  "Up to this many key-images, a relocalization over the whole map needs no more located features "
                  "than a local one; beyond, --global-features-per-log more per factor e")
      ->capture_default_str();
  cmd->add_option("--single-key-image-gate-candidates", args->options.single_key_image_gate_candidates,
                  "A place verified by one key-image only is accepted over the whole map with no more located "
                  "features than a local relocalization up to this many key-images, --global-features-per-log more "
                  "per factor e beyond (0: never)")
      ->capture_default_str();
  cmd->add_option("--global-features-per-log", args->options.global_features_per_log_candidates,
                  "Located features a relocalization over the whole map needs in addition per factor e of "
                  "key-images beyond --global-gate-candidates")
      ->capture_default_str();
  cmd->add_option("--confident-inliers", args->options.retrieval_confident_inliers,
                  "Verification stops at the first key-image with this many inliers")->capture_default_str();
  cmd->add_flag("!--sift", args->options.binary_relocalization,
                "Relocalize with SIFT extracted at run time (as before issue 16), not the stored binary key-points");
  cmd->add_flag("!--no-visual-words", args->options.visual_word_retrieval,
                "Rank the whole map by appearance thumbnails alone, not fused with visual words");
  cmd->add_flag("--relocalization-affine", args->options.relocalization_affine_fallback,
                "Align the mapped features a relocalization locates with the affine fallback too (`repeat "
                "--relocalization-affine`)");
  cmd->add_option("--start-alternative-starts", args->options.start_alternative_starts,
                  "Align a mapped feature that fails from the median of the matches around it from each of this many "
                  "nearest matches (`repeat --start-alternative-starts`; 0: the median alone)")
      ->check(CLI::Range(0, 100))
      ->capture_default_str();
  cmd->callback([args]() {
    std::string error;
    if (!args->options.Check(&error)) throw InputError("bench options", error);
    RunKidnap(*args);
  });

  auto retrieval = std::make_shared<RetrievalArguments>();
  CLI::App* rcmd = bench->add_subcommand(
      "retrieval", "Retrieval quality: rank of the true arc's key-images for every frame of a drive (recall@1, @5)");
  rcmd->add_option("--map", retrieval->map, "Map file written by `retrace teach`")->required();
  rcmd->add_option("--sequence", retrieval->sequence, "Drive with KITTI poses.txt")->required();
  rcmd->add_option("--every", retrieval->every, "Query every N-th frame of the drive")->check(CLI::PositiveNumber);
  rcmd->add_option("--vocabulary-branching", retrieval->options.vocabulary.branching, "Visual words: children per node")
      ->capture_default_str();
  rcmd->add_option("--vocabulary-depth", retrieval->options.vocabulary.depth, "Visual words: levels of the tree")
      ->capture_default_str();
  rcmd->callback([retrieval]() { RunRetrieval(*retrieval); });

  RegisterBenchHeadingCommand(bench);
}

}  // namespace retrace
