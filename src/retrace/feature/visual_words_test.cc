#include "retrace/feature/visual_words.h"

#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "retrace/feature/binary_features.h"
#include "retrace/feature/synthetic_texture.h"

namespace retrace {
namespace {

// `clusters` random 32-byte descriptors, each with `copies` noisy copies (`flips` random bits flipped); row
// c * copies + i is copy i of cluster c.
cv::Mat ClusteredDescriptors(int clusters, int copies, int flips, uint64_t seed, cv::Mat* centres = nullptr) {
  std::mt19937_64 rng(seed);
  cv::Mat centre_rows(clusters, 32, CV_8U);
  cv::randu(centre_rows, 0, 256);  // OpenCV's own generator, seeded below
  cv::Mat rows(clusters * copies, 32, CV_8U);
  std::uniform_int_distribution<int> bit(0, 255);
  for (int c = 0; c < clusters; ++c) {
    for (int i = 0; i < copies; ++i) {
      cv::Mat row = rows.row(c * copies + i);
      centre_rows.row(c).copyTo(row);
      for (int f = 0; f < flips; ++f) {
        const int b = bit(rng);
        row.at<uchar>(b >> 3) ^= static_cast<uchar>(1 << (b & 7));
      }
    }
  }
  if (centres != nullptr) *centres = centre_rows;
  return rows;
}

TEST(VisualVocabulary, NoisyCopiesOfOneDescriptorShareAWordAndOthersDoNot) {
  cv::theRNG().state = 7;
  cv::Mat centres;
  const int clusters = 6, copies = 30;
  // 6 of 256 bits flipped: a copy lies ~12 bits from another copy, ~128 from another cluster.
  const cv::Mat rows = ClusteredDescriptors(clusters, copies, 6, 3, &centres);
  VisualVocabularyOptions options;
  options.branching = 6;
  options.depth = 2;
  // 180 descriptors split into 6 children; a child of 30 < 6 x 10 stays a leaf.
  options.min_descriptors_per_child = 10;
  const VisualVocabulary vocabulary = VisualVocabulary::Train(rows, options);
  EXPECT_EQ(vocabulary.size(), clusters);
  EXPECT_EQ(vocabulary.descriptor_bytes(), 32);
  const std::vector<int> words = vocabulary.Words(rows);
  std::vector<int> cluster_word(clusters);
  for (int c = 0; c < clusters; ++c) {
    // Each cluster's copies and its centre in one word (the per-bit majority of the copies is the centre) ...
    cluster_word[c] = vocabulary.Word(centres.ptr<uchar>(c));
    for (int i = 0; i < copies; ++i) EXPECT_EQ(words[c * copies + i], cluster_word[c]) << c << " " << i;
  }
  // ... and no two clusters in one.
  std::sort(cluster_word.begin(), cluster_word.end());
  EXPECT_EQ(std::unique(cluster_word.begin(), cluster_word.end()) - cluster_word.begin(), clusters);
}

TEST(VisualVocabulary, SmallNodesAreNotSplitAndTrainingIsDeterministic) {
  cv::theRNG().state = 11;
  const cv::Mat rows = ClusteredDescriptors(5, 8, 4, 5);
  VisualVocabularyOptions options;
  options.branching = 10;
  options.depth = 3;
  options.min_descriptors_per_child = 5;  // 40 descriptors < 10 x 5: the root stays a leaf
  EXPECT_EQ(VisualVocabulary::Train(rows, options).size(), 1);
  options.branching = 4;  // 40 >= 4 x 5: one split, then 8-12 per child < 20: leaves
  const VisualVocabulary a = VisualVocabulary::Train(rows, options);
  const VisualVocabulary b = VisualVocabulary::Train(rows, options);
  EXPECT_EQ(a.size(), 4);
  EXPECT_EQ(a.Words(rows), b.Words(rows));
  // An empty input: one word, every descriptor in it; a default-constructed vocabulary answers word 0.
  EXPECT_EQ(VisualVocabulary::Train(cv::Mat(), options).size(), 1);
  EXPECT_EQ(VisualVocabulary::Train(cv::Mat(), options).Word(rows.ptr<uchar>(0)), 0);
  EXPECT_EQ(VisualVocabulary().Word(rows.ptr<uchar>(0)), 0);
  // Descriptors of another width than 8-32 bytes in steps of 8 are refused.
  EXPECT_THROW(VisualVocabulary::Train(cv::Mat(4, 12, CV_8U, cv::Scalar(1)), options), std::invalid_argument);
}

TEST(VisualVocabulary, OptionsAreChecked) {
  VisualVocabularyOptions options;
  std::string error;
  EXPECT_TRUE(options.Check(&error));
  options.branching = 1;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_EQ(error, "branching must be in 2..64");
  options = {};
  options.depth = 0;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_THROW(VisualVocabulary::Train(cv::Mat(), options), std::invalid_argument);
}

TEST(VisualWordIndex, ScoresAreTheL1SimilarityOfTfIdfVectors) {
  VisualWordIndex index(10);
  // Word 0 is in every image (idf 0: it tells nothing); images 0 and 1 share word 1.
  EXPECT_EQ(index.Add({0, 1, 1, 2}), 0u);
  EXPECT_EQ(index.Add({0, 1, 3, 3}), 1u);
  EXPECT_EQ(index.Add({0, 4, 5, 6}), 2u);
  EXPECT_EQ(index.size(), 3u);
  const std::vector<size_t> all = {0, 1, 2};
  // An image scores 1 against itself (equal unit vectors) ...
  std::vector<double> scores = index.Score({0, 1, 1, 2}, all);
  EXPECT_NEAR(scores[0], 1.0, 1e-6);
  // ... and against image 1 the share of word 1: idf ln(3/2) for words 1 and ln(3) for 2 and 3; image 0 weighs
  // word 1 by 0.5 ln 1.5 and word 2 by 0.25 ln 3, normalised; image 1 word 1 by 0.25 ln 1.5, word 3 by 0.5 ln 3.
  const double l15 = std::log(1.5), l3 = std::log(3.0);
  const double q1 = 0.5 * l15 / (0.5 * l15 + 0.25 * l3);
  const double d1 = 0.25 * l15 / (0.25 * l15 + 0.5 * l3);
  EXPECT_NEAR(scores[1], std::min(q1, d1), 1e-6);
  EXPECT_NEAR(scores[2], 0.0, 1e-12);  // only word 0 in common
  // Ranking, restricted to the entries asked for, in their order of similarity.
  EXPECT_EQ(index.Rank({3, 3, 0}, all), (std::vector<size_t>{1, 0, 2}));
  EXPECT_EQ(index.Rank({4, 5}, {0, 2}), (std::vector<size_t>{2, 0}));
  // Words outside the vocabulary are ignored.
  EXPECT_NEAR(index.Score({1, 1, 2, 0, 99, -1}, {0})[0], index.Score({1, 1, 2, 0}, {0})[0], 1e-12);
}

TEST(VisualWords, RetrievalFindsTheSameSceneUnderAnotherViewpointAndLight) {
  // Eight textured scenes; the query is scene 5 seen closer, shifted, darker. Its key-points' words find it first.
  const BinaryFeatureOptions features;
  std::vector<cv::Mat> descriptors;
  for (int scene = 0; scene < 8; ++scene) {
    descriptors.push_back(ExtractBinaryFeatures(ClutteredTexture(320, 240, 100 + scene), features).descriptors);
  }
  VisualVocabularyOptions options;
  options.depth = 3;
  const VisualWords words = BuildVisualWords(descriptors, options);
  EXPECT_EQ(words.index.size(), 8u);
  cv::Mat transform = cv::getRotationMatrix2D(cv::Point2f(160, 120), 0.0, 1.12);
  transform.at<double>(0, 2) += 7.0;
  cv::Mat warped, query;
  cv::warpAffine(ClutteredTexture(320, 240, 105), warped, transform, cv::Size(320, 240), cv::INTER_LINEAR,
                 cv::BORDER_CONSTANT, cv::Scalar(128));
  warped.convertTo(query, CV_8U, 0.75, 10.0);
  const std::vector<int> query_words = words.vocabulary.Words(ExtractBinaryFeatures(query, features).descriptors);
  const std::vector<size_t> all = {0, 1, 2, 3, 4, 5, 6, 7};
  const std::vector<double> scores = words.index.Score(query_words, all);
  const std::vector<size_t> ranked = words.index.Rank(query_words, all);
  ASSERT_EQ(ranked.front(), 5u);
  // Not a near tie: the scene scores well above the best other one.
  EXPECT_GT(scores[5], 1.5 * scores[ranked[1]]) << scores[5] << " against " << scores[ranked[1]];
}

TEST(FuseRankings, ReciprocalRankFusionOfTwoRankings) {
  // 0 and 2 score 1/60 + 1/62 each, 1 scores 2/61 (a little less); the tie keeps the first ranking's order.
  EXPECT_EQ(FuseRankings({0, 1, 2}, {2, 1, 0}), (std::vector<size_t>{0, 2, 1}));
  // 3 (ranks 1 and 0) before 7 (0 and 3) before 4 (2 and 1) before 5 (3 and 2).
  EXPECT_EQ(FuseRankings({7, 3, 4, 5}, {3, 4, 5, 7}), (std::vector<size_t>{3, 7, 4, 5}));
  // Items of only one ranking are kept.
  EXPECT_EQ(FuseRankings({1}, {2, 1}), (std::vector<size_t>{1, 2}));
  EXPECT_TRUE(FuseRankings({}, {}).empty());
}

}  // namespace
}  // namespace retrace
