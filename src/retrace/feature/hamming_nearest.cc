#include "retrace/feature/hamming_nearest.h"

#include <cstdint>
#include <limits>
#include <stdexcept>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define RETRACE_HAMMING_X86 1
#include <immintrin.h>
#endif

namespace retrace {
namespace {

constexpr int kNone = std::numeric_limits<int>::max();

// The Hamming distance of two descriptors of kWords 64-bit words (the word count a compile-time constant, so that
// the loop unrolls).
template <int kWords>
inline int HammingDistance(const uint64_t* a, const uint64_t* b) {
  int d = 0;
  for (int w = 0; w < kWords; ++w) d += __builtin_popcountll(a[w] ^ b[w]);
  return d;
}

// One pair at a time, keeping only the running minima: a table of every distance (4 bytes per pair, 9.7 MB for a
// 1226x370 frame's 2430 key-points against a key-image's 1000) would be written and read back through memory. The
// body is the same for the portable build and the POPCNT one.
#define RETRACE_HAMMING_NEAREST_SCALAR_BODY                             \
  const int n = query.rows, m = train.rows;                             \
  int* best_query_d = nearest->best_query_d.data();                     \
  int* best_query_of_train = nearest->best_query_of_train.data();       \
  for (int i = 0; i < n; ++i) {                                         \
    const uint64_t* q = query.ptr<uint64_t>(i);                         \
    int best = -1, best_d = kNone, second_d = kNone;                    \
    for (int j = 0; j < m; ++j) {                                       \
      const int d = HammingDistance<kWords>(q, train.ptr<uint64_t>(j)); \
      if (d < best_d) {                                                 \
        second_d = best_d;                                              \
        best_d = d;                                                     \
        best = j;                                                       \
      } else if (d < second_d) {                                        \
        second_d = d;                                                   \
      }                                                                 \
      if (d < best_query_d[j]) {                                        \
        best_query_d[j] = d;                                            \
        best_query_of_train[j] = i;                                     \
      }                                                                 \
    }                                                                   \
    nearest->best[i] = best;                                            \
    nearest->best_d[i] = best_d;                                        \
    nearest->second_d[i] = second_d;                                    \
  }

template <int kWords>
void NearestPortable(const cv::Mat& query, const cv::Mat& train, HammingNearest* nearest) {
  RETRACE_HAMMING_NEAREST_SCALAR_BODY
}

#ifdef RETRACE_HAMMING_X86
template <int kWords>
__attribute__((target("popcnt"))) void NearestPopcnt(const cv::Mat& query, const cv::Mat& train,
                                                     HammingNearest* nearest) {
  RETRACE_HAMMING_NEAREST_SCALAR_BODY
}
#endif
#undef RETRACE_HAMMING_NEAREST_SCALAR_BODY

// What the vector kernels share: the train descriptors word-major in blocks of kLanes (word w of descriptor
// b * kLanes + l at ((b * kWords + w) * kLanes + l); the block past the last descriptor padded with zeros, masked out
// by the kernels) and, per train descriptor, its nearest query so far as lanes of `Minimum` (64 bits for AVX2, whose
// lanes are the 64-bit words; 32 for AVX-512, which packs two blocks of words into one register of distances).
template <int kWords, int kLanes, typename Minimum = int64_t>
struct TrainBlocks {
  explicit TrainBlocks(const cv::Mat& train)
      : blocks((train.rows + kLanes - 1) / kLanes),
        valid_in_last(train.rows - (blocks - 1) * kLanes),
        words(static_cast<size_t>(blocks) * kWords * kLanes, 0),
        best_query_d(static_cast<size_t>(blocks) * kLanes, kNone),
        best_query(best_query_d.size(), -1) {
    for (int j = 0; j < train.rows; ++j) {
      const uint64_t* row = train.ptr<uint64_t>(j);
      const size_t block = static_cast<size_t>(j / kLanes), lane = static_cast<size_t>(j % kLanes);
      for (int w = 0; w < kWords; ++w) words[(block * kWords + w) * kLanes + lane] = row[w];
    }
  }
  const uint64_t* Words(int block, int word) const { return &words[(size_t(block) * kWords + word) * kLanes]; }
  // The per-train minima written back as ints.
  void StoreInto(HammingNearest* nearest) const {
    for (size_t j = 0; j < nearest->best_query_d.size(); ++j) {
      nearest->best_query_d[j] = static_cast<int>(best_query_d[j]);
      nearest->best_query_of_train[j] = static_cast<int>(best_query[j]);
    }
  }

  const int blocks, valid_in_last;
  std::vector<uint64_t> words;
  std::vector<Minimum> best_query_d, best_query;
};

// The lanes' running minima of one query row merged: the nearest (lowest index on a tie) and, as second, the
// smaller of its lane's second and the other lanes' nearest.
template <int kLanes, typename Lane>
void MergeLanes(const Lane* best, const Lane* second, const Lane* best_j, int i, HammingNearest* nearest) {
  int lane = 0;
  for (int l = 1; l < kLanes; ++l) {
    // A lane without any descriptor (the last block's padding, best_j -1) holds kNone: never the nearest.
    if (best[l] < best[lane] || (best[l] == best[lane] && best_j[l] < best_j[lane])) lane = l;
  }
  Lane second_d = second[lane];
  for (int l = 0; l < kLanes; ++l) {
    if (l != lane && best[l] < second_d) second_d = best[l];
  }
  nearest->best[i] = static_cast<int>(best_j[lane]);
  nearest->best_d[i] = static_cast<int>(best[lane]);
  nearest->second_d[i] = static_cast<int>(second_d);
}

#ifdef RETRACE_HAMMING_X86
template <int kWords>
__attribute__((target("avx2"))) void NearestAvx2(const cv::Mat& query, const cv::Mat& train, HammingNearest* nearest) {
  constexpr int kLanes = 4;
  TrainBlocks<kWords, kLanes> train_blocks(train);
  const int blocks = train_blocks.blocks;
  // Bit counts of the 16 nibbles, in both 128-bit halves (the byte shuffle looks up within each half).
  const __m256i nibble_counts = _mm256_setr_epi8(0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4,  //
                                                 0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4);
  const __m256i low_nibbles = _mm256_set1_epi8(0x0f);
  const __m256i none = _mm256_set1_epi64x(kNone);
  const __m256i step = _mm256_set1_epi64x(kLanes);
  // The padded lanes of the last block: never nearer than anything.
  const __m256i last_padding =
      _mm256_cmpgt_epi64(_mm256_setr_epi64x(0, 1, 2, 3), _mm256_set1_epi64x(train_blocks.valid_in_last - 1));
  alignas(32) int64_t lane_best[kLanes], lane_second[kLanes], lane_best_j[kLanes];
  for (int i = 0; i < query.rows; ++i) {
    const uint64_t* q = query.ptr<uint64_t>(i);
    __m256i query_words[kWords];
    for (int w = 0; w < kWords; ++w) query_words[w] = _mm256_set1_epi64x(static_cast<int64_t>(q[w]));
    const __m256i query_index = _mm256_set1_epi64x(i);
    __m256i best = none, second = none, best_j = _mm256_set1_epi64x(-1);
    __m256i j = _mm256_setr_epi64x(0, 1, 2, 3);
    for (int b = 0; b < blocks; ++b) {
      // Per byte at most 8 bits per word, 32 over four words: the byte sums cannot overflow before the final sum.
      __m256i byte_counts = _mm256_setzero_si256();
      for (int w = 0; w < kWords; ++w) {
        const __m256i x = _mm256_xor_si256(
            query_words[w], _mm256_loadu_si256(reinterpret_cast<const __m256i*>(train_blocks.Words(b, w))));
        const __m256i low = _mm256_and_si256(x, low_nibbles);
        const __m256i high = _mm256_and_si256(_mm256_srli_epi16(x, 4), low_nibbles);
        byte_counts = _mm256_add_epi8(byte_counts, _mm256_add_epi8(_mm256_shuffle_epi8(nibble_counts, low),
                                                                   _mm256_shuffle_epi8(nibble_counts, high)));
      }
      __m256i d = _mm256_sad_epu8(byte_counts, _mm256_setzero_si256());  // the 64-bit lanes' byte sums
      if (b == blocks - 1) d = _mm256_blendv_epi8(d, none, last_padding);
      // The train descriptors' nearest query (rows in order: the first of equals stays).
      int64_t* block_d = &train_blocks.best_query_d[size_t(b) * kLanes];
      int64_t* block_query = &train_blocks.best_query[size_t(b) * kLanes];
      const __m256i old_d = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(block_d));
      const __m256i nearer_query = _mm256_cmpgt_epi64(old_d, d);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(block_d), _mm256_blendv_epi8(old_d, d, nearer_query));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(block_query),
                          _mm256_blendv_epi8(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(block_query)),
                                             query_index, nearer_query));
      // The query's best and second best per lane.
      const __m256i nearer_than_best = _mm256_cmpgt_epi64(best, d);
      const __m256i nearer_than_second = _mm256_cmpgt_epi64(second, d);
      second = _mm256_blendv_epi8(_mm256_blendv_epi8(second, d, nearer_than_second), best, nearer_than_best);
      best = _mm256_blendv_epi8(best, d, nearer_than_best);
      best_j = _mm256_blendv_epi8(best_j, j, nearer_than_best);
      j = _mm256_add_epi64(j, step);
    }
    _mm256_store_si256(reinterpret_cast<__m256i*>(lane_best), best);
    _mm256_store_si256(reinterpret_cast<__m256i*>(lane_second), second);
    _mm256_store_si256(reinterpret_cast<__m256i*>(lane_best_j), best_j);
    MergeLanes<kLanes>(lane_best, lane_second, lane_best_j, i, nearest);
  }
  train_blocks.StoreInto(nearest);
}

// Lane-wise minimum and maximum of 32-bit integers, through the masked forms (every lane selected): GCC 12's plain
// _mm512_min_epi32 passes an undefined register that -Wmaybe-uninitialized reports.
__attribute__((target("avx512f"))) inline __m512i Min32(__m512i a, __m512i b) {
  return _mm512_mask_min_epi32(a, static_cast<__mmask16>(0xffff), a, b);
}
__attribute__((target("avx512f"))) inline __m512i Max32(__m512i a, __m512i b) {
  return _mm512_mask_max_epi32(a, static_cast<__mmask16>(0xffff), a, b);
}

template <int kWords>
__attribute__((target("avx512f,avx512vpopcntdq"))) void NearestAvx512(const cv::Mat& query, const cv::Mat& train,
                                                                      HammingNearest* nearest) {
  // Sixteen train descriptors per step: their words in two registers of eight 64-bit lanes each, counted there, and
  // the two registers of distances packed into one of sixteen 32-bit lanes (a distance is at most 256), where the
  // minima are kept: the bookkeeping, most of the instructions with eight lanes, is then done once for sixteen.
  constexpr int kLanes = 16;
  TrainBlocks<kWords, kLanes, int32_t> train_blocks(train);
  const int blocks = train_blocks.blocks;
  const __m512i none = _mm512_set1_epi32(kNone);
  const __m512i step = _mm512_set1_epi32(kLanes);
  // The low 32 bits of every 64-bit lane of two registers, the first's lanes first.
  const __m512i low_halves = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
  // The padded lanes of the last block: never nearer than anything.
  const __mmask16 last_valid = static_cast<__mmask16>((1u << train_blocks.valid_in_last) - 1u);
  alignas(64) int32_t lane_best[kLanes], lane_second[kLanes], lane_best_j[kLanes];
  for (int i = 0; i < query.rows; ++i) {
    const uint64_t* q = query.ptr<uint64_t>(i);
    __m512i query_words[kWords];
    for (int w = 0; w < kWords; ++w) query_words[w] = _mm512_set1_epi64(static_cast<int64_t>(q[w]));
    const __m512i query_index = _mm512_set1_epi32(i);
    __m512i best = none, second = none, best_j = _mm512_set1_epi32(-1);
    __m512i j = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    for (int b = 0; b < blocks; ++b) {
      const uint64_t* words = train_blocks.Words(b, 0);
      __m512i low = _mm512_popcnt_epi64(_mm512_xor_si512(query_words[0], _mm512_loadu_si512(words)));
      __m512i high = _mm512_popcnt_epi64(_mm512_xor_si512(query_words[0], _mm512_loadu_si512(words + 8)));
      for (int w = 1; w < kWords; ++w) {
        words = train_blocks.Words(b, w);
        low = _mm512_add_epi64(low, _mm512_popcnt_epi64(_mm512_xor_si512(query_words[w], _mm512_loadu_si512(words))));
        high = _mm512_add_epi64(
            high, _mm512_popcnt_epi64(_mm512_xor_si512(query_words[w], _mm512_loadu_si512(words + 8))));
      }
      __m512i d = _mm512_permutex2var_epi32(low, low_halves, high);
      if (b == blocks - 1) d = _mm512_mask_mov_epi32(none, last_valid, d);
      // The train descriptors' nearest query (rows in order: the first of equals stays).
      int32_t* block_d = &train_blocks.best_query_d[size_t(b) * kLanes];
      int32_t* block_query = &train_blocks.best_query[size_t(b) * kLanes];
      const __mmask16 nearer_query = _mm512_cmplt_epi32_mask(d, _mm512_loadu_si512(block_d));
      _mm512_mask_storeu_epi32(block_d, nearer_query, d);
      _mm512_mask_storeu_epi32(block_query, nearer_query, query_index);
      // The query's best and second best per lane: a distance below the best makes the best the second; one equal
      // to it or between the two is the second (min(second, max(best, d)) in both cases).
      const __mmask16 nearer_than_best = _mm512_cmplt_epi32_mask(d, best);
      second = Min32(second, Max32(best, d));
      best = Min32(best, d);
      best_j = _mm512_mask_mov_epi32(best_j, nearer_than_best, j);
      j = _mm512_add_epi32(j, step);
    }
    _mm512_store_si512(lane_best, best);
    _mm512_store_si512(lane_second, second);
    _mm512_store_si512(lane_best_j, best_j);
    MergeLanes<kLanes>(lane_best, lane_second, lane_best_j, i, nearest);
  }
  train_blocks.StoreInto(nearest);
}
#endif

template <int kWords>
void RunKernel(HammingKernel kernel, const cv::Mat& query, const cv::Mat& train, HammingNearest* nearest) {
  switch (kernel) {
#ifdef RETRACE_HAMMING_X86
    case HammingKernel::kPopcnt:
      NearestPopcnt<kWords>(query, train, nearest);
      return;
    case HammingKernel::kAvx2:
      NearestAvx2<kWords>(query, train, nearest);
      return;
    case HammingKernel::kAvx512:
      NearestAvx512<kWords>(query, train, nearest);
      return;
#endif
    default:
      NearestPortable<kWords>(query, train, nearest);
      return;
  }
}

}  // namespace

bool HammingKernelAvailable(HammingKernel kernel) {
  switch (kernel) {
    case HammingKernel::kAuto:
    case HammingKernel::kPortable:
      return true;
#ifdef RETRACE_HAMMING_X86
    case HammingKernel::kPopcnt:
      return __builtin_cpu_supports("popcnt");
    case HammingKernel::kAvx2:
      return __builtin_cpu_supports("avx2");
    case HammingKernel::kAvx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vpopcntdq");
#endif
    default:
      return false;
  }
}

HammingKernel BestHammingKernel() {
  static const HammingKernel best = [] {
    for (const HammingKernel kernel : {HammingKernel::kAvx512, HammingKernel::kAvx2, HammingKernel::kPopcnt}) {
      if (HammingKernelAvailable(kernel)) return kernel;
    }
    return HammingKernel::kPortable;
  }();
  return best;
}

HammingNearest FindHammingNearest(const cv::Mat& query_in, const cv::Mat& train_in, HammingKernel kernel) {
  const int bytes = query_in.cols;
  CV_Assert(query_in.type() == CV_8U && train_in.type() == CV_8U);
  CV_Assert(train_in.cols == bytes && bytes >= 8 && bytes <= 32 && bytes % 8 == 0);
  if (kernel == HammingKernel::kAuto) {
    kernel = BestHammingKernel();  // available by construction
  } else if (!HammingKernelAvailable(kernel)) {
    throw std::invalid_argument("Hamming kernel not available on this CPU");
  }
  // Rows of whole 64-bit words, 8-byte aligned (cv::Mat's data is 16-byte aligned; a continuous matrix keeps every
  // row so).
  const cv::Mat query = query_in.isContinuous() ? query_in : query_in.clone();
  const cv::Mat train = train_in.isContinuous() ? train_in : train_in.clone();
  HammingNearest nearest;
  nearest.best.assign(query.rows, -1);
  nearest.best_d.assign(query.rows, kNone);
  nearest.second_d.assign(query.rows, kNone);
  nearest.best_query_of_train.assign(train.rows, -1);
  nearest.best_query_d.assign(train.rows, kNone);
  if (query.rows == 0 || train.rows == 0) return nearest;
  switch (bytes / 8) {
    case 1:
      RunKernel<1>(kernel, query, train, &nearest);
      break;
    case 2:
      RunKernel<2>(kernel, query, train, &nearest);
      break;
    case 3:
      RunKernel<3>(kernel, query, train, &nearest);
      break;
    default:
      RunKernel<4>(kernel, query, train, &nearest);
      break;
  }
  return nearest;
}

}  // namespace retrace
