#include "retrace/feature/visual_words.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include <opencv2/core/hal/hal.hpp>

namespace retrace {

bool VisualVocabularyOptions::Check(std::string* error) const {
  const auto fail = [error](const char* message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (branching < 2 || branching > 64) return fail("branching must be in 2..64");
  if (depth < 1 || depth > 8) return fail("depth must be in 1..8");
  if (min_descriptors_per_child < 1) return fail("min_descriptors_per_child must be >= 1");
  if (iterations < 1) return fail("iterations must be >= 1");
  if (max_training_descriptors < 1) return fail("max_training_descriptors must be >= 1");
  return true;
}

namespace {

int Hamming(const uchar* a, const uchar* b, int bytes) { return cv::hal::normHamming(a, b, bytes); }

// The nearest of `count` centres (rows of `stride` bytes from `centres`) to `descriptor` of `bytes` bytes, by
// Hamming distance over 64-bit words (descriptors of 8-32 bytes, BinaryFeatureOptions::descriptor_bytes); ties to
// the first. Built for POPCNT and plain x86-64, chosen at run time (as wide_baseline.cc's nearest neighbours).
__attribute__((always_inline)) inline int NearestCentreBody(const uchar* descriptor, const uchar* centres, int count,
                                                            size_t stride, int bytes) {
  const int words = bytes / 8;
  uint64_t d[4];
  std::memcpy(d, descriptor, words * 8);
  int best = 0, best_distance = std::numeric_limits<int>::max();
  for (int c = 0; c < count; ++c) {
    uint64_t centre[4];
    std::memcpy(centre, centres + c * stride, words * 8);
    int distance = 0;
    for (int w = 0; w < words; ++w) distance += __builtin_popcountll(d[w] ^ centre[w]);
    if (distance < best_distance) best_distance = distance, best = c;
  }
  return best;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("popcnt"))) int NearestCentrePopcnt(const uchar* descriptor, const uchar* centres, int count,
                                                          size_t stride, int bytes) {
  return NearestCentreBody(descriptor, centres, count, stride, bytes);
}
#endif

int NearestCentre(const uchar* descriptor, const uchar* centres, int count, size_t stride, int bytes) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  if (__builtin_cpu_supports("popcnt")) return NearestCentrePopcnt(descriptor, centres, count, stride, bytes);
#endif
  return NearestCentreBody(descriptor, centres, count, stride, bytes);
}

// Per-bit counts of many descriptors: each byte adds its 8 bits to 8 byte-wide counters packed in one 64-bit word
// (kSpread[v] holds bit b of v in byte b), emptied into the integer counts every 255 descriptors — 32 additions per
// 32-byte descriptor instead of 256.
struct BitCounter {
  explicit BitCounter(int bytes) : packed(bytes, 0), ones(bytes * 8, 0) {}
  void Add(const uchar* descriptor) {
    static const std::array<uint64_t, 256> kSpread = [] {
      std::array<uint64_t, 256> spread{};
      for (int v = 0; v < 256; ++v) {
        for (int b = 0; b < 8; ++b) spread[v] |= static_cast<uint64_t>((v >> b) & 1) << (8 * b);
      }
      return spread;
    }();
    for (size_t j = 0; j < packed.size(); ++j) packed[j] += kSpread[descriptor[j]];
    ++count;
    if (++pending == 255) Flush();
  }
  void Flush() {
    for (size_t j = 0; j < packed.size(); ++j) {
      for (int b = 0; b < 8; ++b) ones[j * 8 + b] += static_cast<int>((packed[j] >> (8 * b)) & 0xff);
      packed[j] = 0;
    }
    pending = 0;
  }
  std::vector<uint64_t> packed;
  std::vector<int> ones;
  int count = 0;
  int pending = 0;
};

}  // namespace

// Builds the tree node by node, breadth first (the children of a node consecutive in nodes_).
class VisualVocabularyBuilder {
 public:
  VisualVocabularyBuilder(const cv::Mat& descriptors, const VisualVocabularyOptions& options)
      : descriptors_(descriptors), options_(options), bytes_(descriptors.cols), rng_(options.seed) {}

  VisualVocabulary Build() {
    VisualVocabulary vocabulary;
    std::vector<cv::Mat> centres;
    vocabulary.nodes_.push_back({});
    centres.push_back(cv::Mat::zeros(1, std::max(bytes_, 1), CV_8U));
    // (node, level, the rows of descriptors_ it holds)
    struct Pending {
      int node;
      int level;
      std::vector<int> rows;
    };
    std::vector<Pending> queue;
    std::vector<int> all(descriptors_.rows);
    std::iota(all.begin(), all.end(), 0);
    queue.push_back({0, 0, std::move(all)});
    for (size_t q = 0; q < queue.size(); ++q) {
      const int node = queue[q].node;
      const int level = queue[q].level;
      std::vector<int> rows = std::move(queue[q].rows);
      const int k = options_.branching;
      if (level >= options_.depth || static_cast<int>(rows.size()) < k * options_.min_descriptors_per_child) {
        vocabulary.nodes_[node].word = vocabulary.num_words_++;
        continue;
      }
      std::vector<cv::Mat> cluster_centres;
      std::vector<std::vector<int>> members;
      Cluster(rows, &cluster_centres, &members);
      vocabulary.nodes_[node].first_child = static_cast<int>(vocabulary.nodes_.size());
      vocabulary.nodes_[node].num_children = static_cast<int>(cluster_centres.size());
      for (size_t c = 0; c < cluster_centres.size(); ++c) {
        const int child = static_cast<int>(vocabulary.nodes_.size());
        vocabulary.nodes_.push_back({});
        centres.push_back(cluster_centres[c]);
        queue.push_back({child, level + 1, std::move(members[c])});
      }
    }
    cv::vconcat(centres, vocabulary.centres_);
    return vocabulary;
  }

 private:
  const uchar* Row(int row) const { return descriptors_.ptr<uchar>(row); }

  // k-majority of `rows` into at most `branching` clusters (fewer when fewer distinct descriptors): k-means++
  // seeding, then assignments to the nearest centre and per-bit majorities until nothing moves or `iterations`.
  void Cluster(const std::vector<int>& rows, std::vector<cv::Mat>* centres, std::vector<std::vector<int>>* members) {
    const int n = static_cast<int>(rows.size());
    const int k = std::min(options_.branching, n);
    // k-means++ (Arthur & Vassilvitskii 2007): each next seed drawn with probability proportional to the squared
    // distance to the nearest seed so far.
    std::vector<double> nearest(n, std::numeric_limits<double>::infinity());
    std::vector<int> seeds = {rows[std::uniform_int_distribution<int>(0, n - 1)(rng_)]};
    while (static_cast<int>(seeds.size()) < k) {
      double total = 0.0;
      for (int i = 0; i < n; ++i) {
        const double d = Hamming(Row(rows[i]), Row(seeds.back()), bytes_);
        nearest[i] = std::min(nearest[i], d * d);
        total += nearest[i];
      }
      if (total <= 0.0) break;  // every descriptor equals a seed
      double pick = std::uniform_real_distribution<double>(0.0, total)(rng_);
      int chosen = n - 1;
      for (int i = 0; i < n; ++i) {
        pick -= nearest[i];
        if (pick <= 0.0 && nearest[i] > 0.0) {
          chosen = i;
          break;
        }
      }
      seeds.push_back(rows[chosen]);
    }
    centres->clear();
    for (const int s : seeds) centres->push_back(descriptors_.row(s).clone());
    const int clusters = static_cast<int>(centres->size());
    std::vector<int> assignment(n, -1);
    cv::Mat packed_centres(clusters, bytes_, CV_8U);
    for (int iteration = 0; iteration < options_.iterations; ++iteration) {
      for (int c = 0; c < clusters; ++c) (*centres)[c].copyTo(packed_centres.row(c));
      bool moved = false;
      for (int i = 0; i < n; ++i) {
        const int best = NearestCentre(Row(rows[i]), packed_centres.data, clusters, packed_centres.step, bytes_);
        moved |= assignment[i] != best;
        assignment[i] = best;
      }
      if (!moved) break;
      // Per-bit majority of each cluster's descriptors (ties to 0); an emptied cluster keeps its centre.
      std::vector<BitCounter> counters(clusters, BitCounter(bytes_));
      for (int i = 0; i < n; ++i) counters[assignment[i]].Add(Row(rows[i]));
      for (int c = 0; c < clusters; ++c) {
        BitCounter& counter = counters[c];
        if (counter.count == 0) continue;
        counter.Flush();
        uchar* centre = (*centres)[c].ptr<uchar>();
        std::fill(centre, centre + bytes_, 0);
        for (int b = 0; b < bytes_ * 8; ++b) {
          if (2 * counter.ones[b] > counter.count) centre[b >> 3] |= static_cast<uchar>(1 << (b & 7));
        }
      }
    }
    members->assign(clusters, {});
    for (int i = 0; i < n; ++i) (*members)[assignment[i]].push_back(rows[i]);
    // Drop clusters left empty (their descriptors went elsewhere): no leaf without descriptors.
    for (int c = clusters - 1; c >= 0; --c) {
      if (!(*members)[c].empty()) continue;
      centres->erase(centres->begin() + c);
      members->erase(members->begin() + c);
    }
  }

  const cv::Mat& descriptors_;
  const VisualVocabularyOptions& options_;
  const int bytes_;
  std::mt19937_64 rng_;
};

VisualVocabulary VisualVocabulary::Train(const cv::Mat& descriptors, const VisualVocabularyOptions& options) {
  std::string error;
  if (!options.Check(&error)) throw std::invalid_argument("VisualVocabularyOptions: " + error);
  if (!descriptors.empty() && (descriptors.type() != CV_8U || descriptors.cols % 8 != 0 || descriptors.cols > 32)) {
    throw std::invalid_argument("VisualVocabulary::Train: descriptors must be rows of 8, 16, 24 or 32 bytes (CV_8U)");
  }
  cv::Mat training = descriptors;
  if (descriptors.rows > options.max_training_descriptors) {
    // A random subset, in the order of the input (deterministic for a seed).
    std::vector<int> rows(descriptors.rows);
    std::iota(rows.begin(), rows.end(), 0);
    std::mt19937_64 rng(options.seed);
    std::shuffle(rows.begin(), rows.end(), rng);
    rows.resize(options.max_training_descriptors);
    std::sort(rows.begin(), rows.end());
    training = cv::Mat(static_cast<int>(rows.size()), descriptors.cols, CV_8U);
    for (size_t i = 0; i < rows.size(); ++i) descriptors.row(rows[i]).copyTo(training.row(static_cast<int>(i)));
  } else if (!training.isContinuous()) {
    training = training.clone();
  }
  if (training.empty()) training = cv::Mat(0, std::max(descriptors.cols, 1), CV_8U);
  return VisualVocabularyBuilder(training, options).Build();
}

int VisualVocabulary::Word(const uchar* descriptor) const {
  if (nodes_.empty()) return 0;  // a default-constructed vocabulary: one word
  int node = 0;
  while (nodes_[node].first_child >= 0) {
    node = nodes_[node].first_child + NearestCentre(descriptor, centres_.ptr<uchar>(nodes_[node].first_child),
                                                    nodes_[node].num_children, centres_.step, centres_.cols);
  }
  return nodes_[node].word;
}

std::vector<int> VisualVocabulary::Words(const cv::Mat& descriptors) const {
  CV_Assert(descriptors.empty() || (descriptors.type() == CV_8U && descriptors.cols == centres_.cols));
  std::vector<int> words(descriptors.rows);
  for (int i = 0; i < descriptors.rows; ++i) words[i] = Word(descriptors.ptr<uchar>(i));
  return words;
}

namespace {

// Each distinct word of `words` with its share of them.
std::vector<std::pair<int, float>> TermFrequencies(const std::vector<int>& words) {
  std::vector<int> sorted = words;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::pair<int, float>> frequencies;
  const float share = words.empty() ? 0.0f : 1.0f / static_cast<float>(words.size());
  for (size_t i = 0; i < sorted.size();) {
    size_t j = i;
    while (j < sorted.size() && sorted[j] == sorted[i]) ++j;
    frequencies.emplace_back(sorted[i], share * static_cast<float>(j - i));
    i = j;
  }
  return frequencies;
}

}  // namespace

size_t VisualWordIndex::Add(const std::vector<int>& words) {
  const size_t entry = num_entries_++;
  for (const auto& [word, frequency] : TermFrequencies(words)) {
    if (word < 0 || word >= static_cast<int>(postings_.size())) continue;
    postings_[word].push_back({static_cast<uint32_t>(entry), frequency});
  }
  weights_current_ = false;
  return entry;
}

void VisualWordIndex::ShrinkToFit() {
  for (std::vector<Posting>& postings : postings_) postings.shrink_to_fit();
}

void VisualWordIndex::UpdateWeights() const {
  if (weights_current_) return;
  idf_.assign(postings_.size(), 0.0f);
  entry_norm_.assign(num_entries_, 0.0f);
  for (size_t w = 0; w < postings_.size(); ++w) {
    if (postings_[w].empty()) continue;
    idf_[w] = static_cast<float>(std::log(static_cast<double>(num_entries_) / postings_[w].size()));
    for (const Posting& p : postings_[w]) entry_norm_[p.entry] += p.term_frequency * idf_[w];
  }
  weights_current_ = true;
}

std::vector<double> VisualWordIndex::Score(const std::vector<int>& query_words,
                                           const std::vector<size_t>& entries) const {
  UpdateWeights();
  std::vector<double> scores(entries.size(), 0.0);
  if (entries.empty()) return scores;
  // Slot of each requested entry in `scores` (-1: not requested).
  std::vector<int> slot(num_entries_, -1);
  for (size_t i = 0; i < entries.size(); ++i) {
    if (entries[i] < num_entries_) slot[entries[i]] = static_cast<int>(i);
  }
  const std::vector<std::pair<int, float>> query = TermFrequencies(query_words);
  double query_norm = 0.0;
  for (const auto& [word, frequency] : query) {
    if (word >= 0 && word < static_cast<int>(idf_.size())) query_norm += frequency * idf_[word];
  }
  if (query_norm <= 0.0) return scores;
  for (const auto& [word, frequency] : query) {
    if (word < 0 || word >= static_cast<int>(idf_.size()) || idf_[word] <= 0.0f) continue;
    const double q = frequency * idf_[word] / query_norm;
    for (const Posting& p : postings_[word]) {
      const int s = slot[p.entry];
      if (s < 0 || entry_norm_[p.entry] <= 0.0f) continue;
      const double d = p.term_frequency * idf_[word] / entry_norm_[p.entry];
      scores[s] += std::min(q, d);
    }
  }
  return scores;
}

std::vector<size_t> VisualWordIndex::Rank(const std::vector<int>& query_words,
                                          const std::vector<size_t>& entries) const {
  const std::vector<double> scores = Score(query_words, entries);
  std::vector<size_t> order(entries.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return scores[a] > scores[b] || (scores[a] == scores[b] && entries[a] < entries[b]);
  });
  std::vector<size_t> ranked;
  ranked.reserve(order.size());
  for (const size_t i : order) ranked.push_back(entries[i]);
  return ranked;
}

VisualWords BuildVisualWords(size_t num_images, const std::function<cv::Mat(size_t)>& descriptors_of,
                             const VisualVocabularyOptions& options) {
  // Evenly spaced rows of each image, at most an equal share of the training budget from each (every row of a map
  // of up to 200 key-images of 1000 descriptors).
  const size_t budget = static_cast<size_t>(options.max_training_descriptors);
  const size_t share = num_images == 0 ? 0 : (budget + num_images - 1) / num_images;
  std::vector<uchar> rows;  // the training descriptors, one after the other
  int bytes = 0;
  for (size_t image = 0; image < num_images; ++image) {
    const cv::Mat d = descriptors_of(image);
    if (d.empty() || d.type() != CV_8U || (bytes != 0 && d.cols != bytes)) continue;
    bytes = d.cols;
    const int take = static_cast<int>(std::min(static_cast<size_t>(d.rows), share));
    for (int i = 0; i < take; ++i) {
      const uchar* row = d.ptr<uchar>(static_cast<int>(static_cast<int64_t>(i) * d.rows / take));
      rows.insert(rows.end(), row, row + bytes);
    }
  }
  const cv::Mat training =
      bytes == 0 ? cv::Mat() : cv::Mat(static_cast<int>(rows.size() / bytes), bytes, CV_8U, rows.data());
  VisualWords words{VisualVocabulary::Train(training, options), VisualWordIndex()};
  rows = {};
  words.index = VisualWordIndex(words.vocabulary.size());
  for (size_t image = 0; image < num_images; ++image) {
    const cv::Mat d = descriptors_of(image);
    words.index.Add(!d.empty() && d.cols == words.vocabulary.descriptor_bytes() ? words.vocabulary.Words(d)
                                                                                : std::vector<int>());
  }
  words.index.ShrinkToFit();
  return words;
}

VisualWords BuildVisualWords(const std::vector<cv::Mat>& descriptors, const VisualVocabularyOptions& options) {
  return BuildVisualWords(
      descriptors.size(), [&descriptors](size_t i) { return descriptors[i]; }, options);
}

std::vector<size_t> FuseRankings(const std::vector<size_t>& a, const std::vector<size_t>& b, double k) {
  std::unordered_map<size_t, double> score;
  for (const std::vector<size_t>* ranking : {&a, &b}) {
    for (size_t r = 0; r < ranking->size(); ++r) score[(*ranking)[r]] += 1.0 / (k + static_cast<double>(r));
  }
  std::vector<size_t> fused = a;
  const std::unordered_set<size_t> in_a(a.begin(), a.end());
  for (const size_t item : b) {
    if (!in_a.count(item)) fused.push_back(item);
  }
  std::stable_sort(fused.begin(), fused.end(), [&score](size_t x, size_t y) { return score[x] > score[y]; });
  return fused;
}

}  // namespace retrace
