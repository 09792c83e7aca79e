// Repeat on real data against topological ground truth (design §9): kitti07 (160 frames, ~90 m), map taught from
// the even frames, repeat on the odd frames, clean and perturbed.

#include <cstdlib>
#include <iostream>
#include <memory>

#include <gtest/gtest.h>

#include "retrace/camera/camera_io.h"
#include "retrace/dataset/ground_truth.h"
#include "retrace/dataset/sequence.h"
#include "retrace/image/image_utils.h"
#include "retrace/image/perturbation.h"
#include "retrace/map/map_database.h"
#include "retrace/repeat/evaluation.h"
#include "retrace/repeat/localizer.h"
#include "retrace/repeat/map_loading.h"
#include "retrace/teach/teacher.h"
#include "retrace/util/testing.h"

namespace retrace {
namespace {

struct RepeatRun {
  TopologicalEvaluation evaluation;
  std::vector<FrameResult> results;
  int first_localized = -1;  // index in the repeat sequence of the first localized frame
};

class RepeatKitti : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    kitti_ = testing::SharedDataPath("kitti07");
    if (kitti_.empty()) return;
    std::unique_ptr<Sequence> sequence = OpenSequence(kitti_);
    camera_ = ReadCameraFile(*sequence->calibration_file(), sequence->image_size()).release();
    truth_ = new std::vector<TimedPose>(ReadKittiPoses(*sequence->ground_truth_file()));
    SubsampledSequence even(std::move(sequence), 2, 0);
    Teacher teacher(*camera_, TeachOptions(), nullptr);
    while (auto frame = even.Next()) teacher.AddFrame(*frame);
    teacher.Finish();
    map_ = new Map(teacher.map());
  }
  static void TearDownTestSuite() {
    delete map_;
    delete camera_;
    delete truth_;
  }

  void SetUp() override {
    if (kitti_.empty()) GTEST_SKIP() << "shared data 'kitti07' not found; skipping";
  }

  static RepeatRun Run(size_t step, size_t offset, const PerturbationOptions& perturbation, arc_t start_arc,
                       const std::string& label) {
    SubsampledSequence sequence(OpenSequence(kitti_), step, offset);
    Localizer localizer(*map_, *camera_);
    if (start_arc != kInvalidArcId) localizer.SetStartArc(start_arc);
    RepeatRun run;
    std::vector<RepeatRecord> records;
    while (auto frame = sequence.Next()) {
      if (!perturbation.IsIdentity()) frame->image = PerturbImage(frame->image, frame->index, perturbation);
      FrameResult result = localizer.ProcessFrame(*frame);
      if (run.first_localized < 0 && result.state == LocalizerState::kTracking) {
        run.first_localized = static_cast<int>(frame->index);
      }
      records.push_back({frame->source_index, result.state == LocalizerState::kTracking, result.arc});
      result.marks.clear();
      run.results.push_back(std::move(result));
    }
    run.evaluation = EvaluateTopological(*map_, *truth_, *truth_, records);
    double seconds = 0;
    for (const FrameResult& r : run.results) seconds += r.seconds;
    std::cout << "kitti07 repeat (" << label << "): " << run.evaluation.Summary() << "; first localized frame "
              << run.first_localized << "; " << 1000.0 * seconds / std::max<size_t>(1, run.results.size())
              << " ms/frame\n";
    for (size_t i = 0; i < run.results.size(); ++i) {
      const FrameTruth& t = run.evaluation.per_frame[i];
      const FrameResult& r = run.results[i];
      if (!t.correct || std::getenv("RETRACE_VERBOSE") != nullptr) {
        std::cout << "  frame " << i << ": " << LocalizerStateName(r.state) << " arc " << r.arc << " true index "
                  << t.true_arc_index << " estimated index " << t.estimated_arc_index << " tracked " << r.tracked
                  << " (" << r.tracked_by_role[0] << "/" << r.tracked_by_role[1] << "/" << r.tracked_by_role[2]
                  << ") resumed " << r.resumed << " rejected " << r.rejected << " dropped " << r.dropped << " drifted " << r.drifted << " sigma_p "
                  << r.sigma_p_from << "/" << r.sigma_p_to << " u " << r.position_on_arc << " tr " << r.transition
                  << " ms " << 1000 * r.seconds << "\n";
      }
    }
    return run;
  }

  // Frame 81 of the odd frames (the middle of the drive), and a uniform grey frame in its place (it verifies no
  // key-image).
  static Frame OddFrame81() {
    SubsampledSequence odd(OpenSequence(kitti_), 2, 81);
    return *odd.Next();
  }
  static Frame Grey(const Frame& frame) {
    Frame grey = frame;
    grey.image = cv::Mat(frame.image.size(), CV_8UC1, cv::Scalar(128));
    return grey;
  }

  static std::filesystem::path kitti_;
  static CameraModel* camera_;
  static Map* map_;
  static std::vector<TimedPose>* truth_;
};

std::filesystem::path RepeatKitti::kitti_;
CameraModel* RepeatKitti::camera_ = nullptr;
Map* RepeatKitti::map_ = nullptr;
std::vector<TimedPose>* RepeatKitti::truth_ = nullptr;

TEST_F(RepeatKitti, OddFramesStayOnTheCorrectArc) {
  const RepeatRun run = Run(2, 1, PerturbationOptions(), 0, "odd frames, start arc 0");
  EXPECT_GE(run.evaluation.FractionCorrect(), 0.99);
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
  EXPECT_LE(run.evaluation.FractionLost(), 0.01);
  // The whole route is traversed: the last frames are on the last arc.
  EXPECT_EQ(run.evaluation.per_frame.back().estimated_arc_index, run.evaluation.per_frame.back().true_arc_index);
}

TEST_F(RepeatKitti, OddFramesWithoutStartArcByRetrieval) {
  const RepeatRun run = Run(2, 1, PerturbationOptions(), kInvalidArcId, "odd frames, retrieval");
  EXPECT_EQ(run.first_localized, 0);
  EXPECT_GE(run.evaluation.FractionCorrect(), 0.99);
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
}

// Issue acceptance for a perturbed repeat: at least 95 % of frames on the correct arc, none wrong by two or more.
void ExpectPerturbedAcceptance(const RepeatRun& run) {
  EXPECT_GE(run.evaluation.FractionCorrect(), 0.95);
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
}

TEST_F(RepeatKitti, DarkerWithGamma) {
  PerturbationOptions perturbation;
  perturbation.brightness = 0.6;
  perturbation.gamma = 1.4;
  const RepeatRun run = Run(2, 1, perturbation, 0, "brightness 0.6, gamma 1.4");
  ExpectPerturbedAcceptance(run);
}

TEST_F(RepeatKitti, PassingOccluder) {
  PerturbationOptions perturbation;
  perturbation.occluder_fraction = 0.4;
  perturbation.occluder_first_frame = 30;
  perturbation.occluder_last_frame = 39;
  const RepeatRun run = Run(2, 1, perturbation, 0, "occluder 40% for 10 frames");
  ExpectPerturbedAcceptance(run);
  // The occluded features are dropped while the occluder passes and resumed (predicted by point transfer and
  // re-aligned) once it has passed: the counts per frame before, during and after.
  const auto mean_tracked = [&](int first, int last) {
    double sum = 0;
    for (int i = first; i <= last; ++i) sum += run.results[i].tracked;
    return sum / (last - first + 1);
  };
  int resumed_after = 0;
  for (int i = 40; i <= 44; ++i) resumed_after += run.results[i].resumed;
  const double before = mean_tracked(25, 29), during = mean_tracked(35, 39), after = mean_tracked(45, 49);
  std::cout << "tracked features per frame: " << before << " before, " << during << " under the occluder, " << after
            << " after (" << resumed_after << " resumed in the 5 frames after it)\n";
  EXPECT_LT(during, 0.85 * before);
  EXPECT_GT(after, during);
  EXPECT_GT(resumed_after, 10);
}

TEST_F(RepeatKitti, EverySecondFrameDropped) {
  const RepeatRun run = Run(4, 1, PerturbationOptions(), 0, "every second odd frame dropped");
  ExpectPerturbedAcceptance(run);
}

TEST_F(RepeatKitti, Noise) {
  PerturbationOptions perturbation;
  perturbation.noise_sigma = 6.0;
  perturbation.seed = 7;
  const RepeatRun run = Run(2, 1, perturbation, 0, "noise sigma 6");
  ExpectPerturbedAcceptance(run);
}

TEST_F(RepeatKitti, StartInTheMiddle) {
  const RepeatRun run = Run(2, 81, PerturbationOptions(), kInvalidArcId, "odd frames from 81, retrieval");
  ASSERT_GE(run.first_localized, 0);
  EXPECT_LT(run.first_localized, 3) << "localized within 3 frames";
  EXPECT_EQ(run.evaluation.wrong_by_two, 0);
  const int after = static_cast<int>(run.results.size()) - std::max(run.first_localized, 0);
  EXPECT_GE(run.evaluation.correct, static_cast<int>(0.95 * after));
  // Retrieval verified a few of the most alike key-images and those around the chosen arc, not the whole map: the
  // start's budget (start_retrieval_shortlist) is not used up, as the first candidate verifies with more than
  // retrieval_confident_inliers.
  const int shortlist = LocalizerOptions().retrieval_shortlist;
  EXPECT_LE(run.results.front().key_images_matched, shortlist + 4) << "of " << map_->nodes().size();
}

// The appearance shortlist finds the arc that verifying every key-image finds, from the same located features.
// A first frame: the start's budget applies, a shortlist of 4 of the map's 18 key-images (the default 20 covers this
// map).
TEST_F(RepeatKitti, RetrievalShortlistAgreesWithMatchingEveryKeyImage) {
  const Frame frame = OddFrame81();
  LocalizerOptions shortlist, every;
  shortlist.start_retrieval_shortlist = 4;
  every.start_retrieval_shortlist = 0;
  const FrameResult shortlisted = Localizer(*map_, *camera_, shortlist).ProcessFrame(frame);
  const FrameResult exhaustive = Localizer(*map_, *camera_, every).ProcessFrame(frame);
  std::cout << "frame 81 from scratch: shortlist verified " << shortlisted.key_images_matched << " key-images in "
            << 1000 * shortlisted.seconds << " ms, every key-image " << exhaustive.key_images_matched << " in "
            << 1000 * exhaustive.seconds << " ms\n";
  ASSERT_EQ(shortlisted.state, LocalizerState::kTracking);
  ASSERT_EQ(exhaustive.state, LocalizerState::kTracking);
  EXPECT_EQ(shortlisted.arc, exhaustive.arc);
  EXPECT_EQ(exhaustive.key_images_matched, static_cast<int>(map_->nodes().size()));
  EXPECT_LT(shortlisted.key_images_matched, exhaustive.key_images_matched / 2);
  EXPECT_GE(shortlisted.tracked, 0.9 * exhaustive.tracked);
}

// The verification budget follows whether the robot has been localized: a fresh localizer (a start) verifies up to
// start_retrieval_shortlist key-images per frame, one lost after it was localized up to retrieval_shortlist. A
// uniform grey frame verifies no key-image, so every budget is used up; no candidate can be confident.
TEST_F(RepeatKitti, StartAndLossHaveTheirOwnVerificationBudgets) {
  const Frame frame = OddFrame81();
  const Frame grey = Grey(frame);
  LocalizerOptions options;
  options.start_retrieval_shortlist = 7;
  options.retrieval_shortlist = 2;
  const FrameResult start = Localizer(*map_, *camera_, options).ProcessFrame(grey);
  EXPECT_NE(start.state, LocalizerState::kTracking);
  EXPECT_EQ(start.key_images_matched, 7);
  Localizer localizer(*map_, *camera_, options);
  ASSERT_EQ(localizer.ProcessFrame(frame).state, LocalizerState::kTracking);
  // The tracks are given up in the grey frame and it is relocalized at once, near where they were lost.
  const FrameResult lost = localizer.ProcessFrame(grey);
  EXPECT_NE(lost.state, LocalizerState::kTracking);
  EXPECT_EQ(lost.key_images_matched, 2);
}

// A start goes on verifying the candidates ranked after the first confident one while they lie within the belief's
// reach of it, and takes the one with most inliers (the first confident one can be a key-image further along the same
// street: LocalizerOptions::retrieval_confident_inliers); a robot lost after it was localized stops at the first
// confident candidate. Frame 81's most alike key-images verify with hundreds of inliers: a start that stopped at the
// first verified as many key-images as the relocalization of the same frame after a loss (2 and 2, measured).
TEST_F(RepeatKitti, AStartVerifiesTheCandidatesNearTheFirstConfidentOne) {
  const Frame frame = OddFrame81();
  const Frame grey = Grey(frame);
  LocalizerOptions options;
  options.start_retrieval_shortlist = 10;
  options.retrieval_shortlist = 10;
  Localizer localizer(*map_, *camera_, options);
  const FrameResult start = localizer.ProcessFrame(frame);
  ASSERT_EQ(start.state, LocalizerState::kTracking);
  // The arc the exhaustive verification of every key-image finds.
  LocalizerOptions every;
  every.start_retrieval_shortlist = 0;
  const FrameResult exhaustive = Localizer(*map_, *camera_, every).ProcessFrame(frame);
  ASSERT_EQ(exhaustive.state, LocalizerState::kTracking);
  EXPECT_EQ(start.arc, exhaustive.arc);
  // Lost in the grey frame (its relocalization verifies nothing), relocalized in the next near where it was lost.
  EXPECT_NE(localizer.ProcessFrame(grey).state, LocalizerState::kTracking);
  const FrameResult relocalized = localizer.ProcessFrame(frame);
  std::cout << "frame 81: the start verified " << start.key_images_matched << " key-images, the relocalization "
            << relocalized.key_images_matched << "\n";
  EXPECT_TRUE(relocalized.bootstrapped);
  EXPECT_GT(start.key_images_matched, relocalized.key_images_matched);
  EXPECT_LT(start.key_images_matched, 10);  // a candidate ranked elsewhere ended the search
}

// The key-images' relocalization signatures that teach stored, and the same computed by the localizer for a map
// without them (a map of an older retrace): frame 81 from scratch is localized on the same arc with the same
// features, and the stored key-points are those LoadMapForLocalizer would compute.
TEST_F(RepeatKitti, StoredSignaturesAreThoseComputedForOlderMaps) {
  const Frame frame = OddFrame81();
  Map without = *map_;
  for (const MapNode& node : map_->nodes()) {
    ASSERT_FALSE(node.signature.empty()) << "teach stores every key-image's signature";
    without.MutableNode(node.id)->signature = KeyImageSignature();
  }
  const MapNode& first = map_->nodes().front();
  const KeyImageSignature computed = Localizer::ComputeSignature(first.image, LocalizerOptions());
  ASSERT_EQ(computed.keypoints.size(), first.signature.keypoints.size());
  EXPECT_EQ(cv::norm(computed.descriptors, first.signature.descriptors, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(computed.appearance, first.signature.appearance, cv::NORM_INF), 0.0);
  const FrameResult stored = Localizer(*map_, *camera_).ProcessFrame(frame);
  const FrameResult recomputed = Localizer(without, *camera_).ProcessFrame(frame);
  ASSERT_EQ(stored.state, LocalizerState::kTracking);
  EXPECT_EQ(stored.arc, recomputed.arc);
  EXPECT_EQ(stored.state, recomputed.state);
  EXPECT_EQ(stored.tracked, recomputed.tracked);
  // The verification budget: the first candidate is confident, so far fewer than the start's budget — at most
  // retrieval_shortlist candidates, plus the key-images of the chosen arc and its neighbours that retrieval did not
  // try.
  EXPECT_LE(stored.key_images_matched, LocalizerOptions().retrieval_shortlist + 4);
}

// A map that stores the descriptors as their differences from its key-images' own (map schema 7, issue 16: kitti07's
// signatures 5 times smaller) gives the localizer the descriptors teach extracted, bit for bit: reconstructed when
// the map is opened, or on demand for a map too large to keep them (max_resident_signatures).
TEST_F(RepeatKitti, DescriptorsStoredAsDifferencesReadBackAsTaught) {
  const auto dir = testing::MakeTempDir("repeat_descriptor_differences");
  int64_t verbatim_bytes = 0, difference_bytes = 0;
  for (const bool differences : {false, true}) {
    auto database = MapDatabase::Create(dir / (differences ? "differences.db" : "verbatim.db"));
    const BinaryFeatureOptions features = TeachOptions().signature_features;
    if (differences) {
      database->SetDescriptorPrediction([features](const cv::Mat& image, const std::vector<cv::KeyPoint>& keypoints) {
        return DescribeBinaryKeyPoints(image, keypoints, features);
      });
    }
    for (const MapNode& node : map_->nodes()) database->WriteNode(node);
    for (const MapArc& arc : map_->arcs()) database->WriteArc(arc);
    database->SetMetadata("signature_features", features.Name());
    database->SetMetadata("signature_appearance", TeachOptions().signature_appearance.Name());
    (differences ? difference_bytes : verbatim_bytes) = database->SignatureBytes();
  }
  // The key-points and thumbnails are stored alike; the descriptors cost a fifth at most.
  int64_t descriptor_bytes = 0;
  for (const MapNode& node : map_->nodes()) descriptor_bytes += node.signature.descriptors.total();
  const int64_t common = verbatim_bytes - descriptor_bytes;
  std::cout << "descriptors: " << descriptor_bytes << " bytes verbatim, " << difference_bytes - common
            << " as differences\n";
  EXPECT_LT(difference_bytes - common, descriptor_bytes / 5);
  for (const int resident : {400, 0}) {
    LocalizerOptions options;
    options.max_resident_signatures = resident;
    const MapForLocalizer loaded = LoadMapForLocalizer(dir / "differences.db", options);
    for (const MapNode& node : map_->nodes()) {
      KeyImageSignature read = loaded.map.Signature(node.id);
      EXPECT_EQ(read.descriptor_residual.empty(), resident > 0) << "node " << node.id;
      Localizer::ResolveSignature(loaded.map, node.id, loaded.options, &read);
      const cv::Mat& descriptors = read.descriptors;
      ASSERT_EQ(descriptors.rows, node.signature.descriptors.rows) << "node " << node.id;
      EXPECT_EQ(cv::norm(descriptors, node.signature.descriptors, cv::NORM_HAMMING), 0.0) << "node " << node.id;
    }
  }
}

// The same repeat at 320 px width (320x97), the resolution of the throughput target: key-images are denser there
// (in the turns the camera passes about one arc per repeat frame), so the continuity of the position along the arc
// must follow the camera's own speed. Before it did, 16 of 80 frames were on a wrong arc, 6 of them by two.
TEST(RepeatKittiAt320, OddFramesStayOnTheCorrectArc) {
  RETRACE_REQUIRE_SHARED_DATA(kitti, "kitti07");
  std::unique_ptr<Sequence> sequence = OpenSequence(kitti);
  const std::unique_ptr<CameraModel> native = ReadCameraFile(*sequence->calibration_file(), sequence->image_size());
  const std::unique_ptr<CameraModel> camera = native->Scaled(320.0 / native->width());
  const std::vector<TimedPose> truth = ReadKittiPoses(*sequence->ground_truth_file());
  const auto resized = [&](Frame frame) {
    cv::Mat small;
    ResizeToWidth(frame.image, camera->width(), &small);
    frame.image = small;
    return frame;
  };
  Teacher teacher(*camera, TeachOptions(), nullptr);
  SubsampledSequence even(OpenSequence(kitti), 2, 0);
  while (auto frame = even.Next()) teacher.AddFrame(resized(*frame));
  teacher.Finish();

  Localizer localizer(teacher.map(), *camera);
  localizer.SetStartArc(teacher.map().arcs().front().id);
  std::vector<RepeatRecord> records;
  SubsampledSequence odd(OpenSequence(kitti), 2, 1);
  while (auto frame = odd.Next()) {
    const FrameResult result = localizer.ProcessFrame(resized(*frame));
    records.push_back({frame->source_index, result.state == LocalizerState::kTracking, result.arc});
  }
  const TopologicalEvaluation evaluation = EvaluateTopological(teacher.map(), truth, truth, records);
  std::cout << "kitti07 repeat at 320 px (odd frames): " << evaluation.Summary() << "\n";
  EXPECT_GE(evaluation.FractionCorrect(), 0.99);
  EXPECT_EQ(evaluation.wrong_by_two, 0);
  EXPECT_LE(evaluation.FractionLost(), 0.01);
}

}  // namespace
}  // namespace retrace
