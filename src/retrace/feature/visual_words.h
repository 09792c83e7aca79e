#pragma once

// Retrieval by visual words (issue 16; design §4.2): the binary descriptors of the relocalization signatures
// (binary_features.h) quantised by a vocabulary tree and scored through an inverted file.
//
// Vocabulary: a tree of `branching` children per node, `depth` levels, built by hierarchical k-majority (k-means with
// Hamming distances, each centre the per-bit majority of its descriptors: Nistér & Stewénius, CVPR 2006, for the tree;
// Gálvez-López & Tardós, T-RO 2012, for binary descriptors), seeded by k-means++. A descriptor's word is the leaf
// reached by descending to the nearest child at each level: branching x depth Hamming distances.
//
// Scoring (Nistér & Stewénius 2006, §4, L1 norm): an image is its vector of word weights tf_w · idf_w, with
// tf_w the word's share of the image's descriptors and idf_w = ln(N / n_w) over the N indexed images, n_w of which
// contain w; both vectors normalised to unit L1 norm. Their L1 distance |q − d|₁ = 2 − 2 Σ_w min(q_w, d_w), so the
// similarity Σ_w min(q_w, d_w) (in [0, 1]) is summed over the words the two share, through the inverted file.
//
// Why here: the appearance thumbnails (global_descriptor.h) rank the right key-image first in 83 % of the validation
// drives' frames, but in a map of 1264 key-images of look-alike blocks it is often 6th-40th. Words carry what the
// verification itself matches: the key-points.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

struct VisualVocabularyOptions {
  // Children per node and levels: up to branching^depth words (10^4).
  int branching = 10;
  int depth = 4;
  // A node is split only when it holds at least this many descriptors per child: a word of a few descriptors
  // describes one key-point in one light, not a kind of key-point (a map of 50 key-images, 50 000 descriptors,
  // gets about 1000 words; one of 1264, 10^4).
  int min_descriptors_per_child = 5;
  // k-majority iterations per node.
  int iterations = 10;
  // Descriptors the tree is trained on at most (a random subset of them); every descriptor is then quantised.
  int max_training_descriptors = 200000;
  uint64_t seed = 1;

  bool Check(std::string* error = nullptr) const;
};

// The vocabulary tree. Descriptors are rows of CV_8U of one width (8-32 bytes).
class VisualVocabulary {
 public:
  VisualVocabulary() = default;
  // Trains on the rows of `descriptors` (CV_8U). An empty input gives a vocabulary of one word.
  static VisualVocabulary Train(const cv::Mat& descriptors, const VisualVocabularyOptions& options = {});

  // The word (0 .. size() - 1) of one descriptor of descriptor_bytes() bytes.
  int Word(const uchar* descriptor) const;
  // The words of every row of `descriptors`.
  std::vector<int> Words(const cv::Mat& descriptors) const;

  int size() const { return num_words_; }
  int descriptor_bytes() const { return centres_.cols; }

 private:
  struct Node {
    int first_child = -1;  // index in nodes_ of the first of num_children consecutive children; -1: a leaf
    int num_children = 0;
    int word = -1;  // leaves only
  };
  // nodes_[i]'s centre is row i of centres_; node 0 is the root (its centre unused).
  std::vector<Node> nodes_;
  cv::Mat centres_;
  int num_words_ = 0;

  friend class VisualVocabularyBuilder;
};

// The tf-idf inverted file over indexed images (see the header comment).
class VisualWordIndex {
 public:
  explicit VisualWordIndex(int num_words = 0) : postings_(static_cast<size_t>(std::max(num_words, 0))) {}

  // Indexes one image by the words of its descriptors; returns its entry (0, 1, ...). The idf weights change with
  // every image added; they are computed when first ranking.
  size_t Add(const std::vector<int>& words);
  size_t size() const { return num_entries_; }
  // Releases the lists' spare capacity once every image is added (a third of 8 MB on 1264 key-images).
  void ShrinkToFit();

  // Similarities in [0, 1] of the query's words to each of `entries`, in the order given.
  std::vector<double> Score(const std::vector<int>& query_words, const std::vector<size_t>& entries) const;
  // `entries` ordered by decreasing similarity (ties by entry).
  std::vector<size_t> Rank(const std::vector<int>& query_words, const std::vector<size_t>& entries) const;

 private:
  struct Posting {
    uint32_t entry;
    float term_frequency;  // the word's share of the entry's descriptors
  };
  void UpdateWeights() const;

  std::vector<std::vector<Posting>> postings_;
  size_t num_entries_ = 0;
  // Per entry: the L1 norm of its tf-idf vector; per word: its idf. Recomputed lazily after Add.
  mutable std::vector<float> idf_;
  mutable std::vector<float> entry_norm_;
  mutable bool weights_current_ = false;
};

// A vocabulary and the inverted file of the images it was trained for (a map's key-images, entry i the map's i-th
// node).
struct VisualWords {
  VisualVocabulary vocabulary;
  VisualWordIndex index;
};

// Trains a vocabulary on up to options.max_training_descriptors rows, at most an equal share of them from each
// image's `descriptors` (evenly spaced), and indexes every image, in order (image i is entry i).
VisualWords BuildVisualWords(const std::vector<cv::Mat>& descriptors, const VisualVocabularyOptions& options = {});
// The same for `num_images` images whose descriptors `descriptors_of(i)` gives (called twice per image: a map's
// descriptors are read from its file one key-image at a time, never all in memory at once).
VisualWords BuildVisualWords(size_t num_images, const std::function<cv::Mat(size_t)>& descriptors_of,
                             const VisualVocabularyOptions& options = {});

// Reciprocal rank fusion (Cormack, Clarke & Büttcher, SIGIR 2009) of two rankings of the same items: each item scored
// by the sum over the rankings of 1 / (k + its rank there, from 0), k = 60 as there (it keeps one ranking's first
// places from deciding alone); ties keep the order of `a`.
std::vector<size_t> FuseRankings(const std::vector<size_t>& a, const std::vector<size_t>& b, double k = 60.0);

}  // namespace retrace
