#include "retrace/map/descriptor_coding.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

cv::Mat RandomDescriptors(int rows, int bytes, uint64_t seed) {
  cv::Mat m(rows, bytes, CV_8U);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

TEST(DescriptorCoding, RoundTripIsExactAndCostsAByteAndOnePerFlippedBit) {
  const cv::Mat predicted = RandomDescriptors(4, 32, 1);
  cv::Mat descriptors = predicted.clone();
  descriptors.at<uint8_t>(1, 0) ^= 0x01;   // bit 0
  descriptors.at<uint8_t>(1, 31) ^= 0x80;  // bit 255
  descriptors.at<uint8_t>(2, 5) ^= 0x18;   // bits 43, 44
  // Row 3: another descriptor altogether (about 128 bits differ): stored as itself.
  RandomDescriptors(1, 32, 2).copyTo(descriptors.row(3));
  const std::vector<uint8_t> code = EncodeDescriptorResidual(descriptors, predicted);
  // Length byte; row 0: 0; row 1: 2 + 0, 255; row 2: 2 + 43, 44; row 3: 255 + 32 bytes.
  ASSERT_EQ(code.size(), 1u + 1u + 3u + 3u + 33u);
  EXPECT_EQ(code[0], 32);
  EXPECT_EQ(code[2], 2);
  EXPECT_EQ(code[3], 0);
  EXPECT_EQ(code[4], 255);
  EXPECT_EQ(code[6], 43);
  EXPECT_EQ(code[7], 44);
  EXPECT_EQ(code[8], 255);
  int bytes = 0;
  EXPECT_FALSE(CheckDescriptorResidual(code, 4, &bytes));
  EXPECT_EQ(bytes, 32);
  cv::Mat decoded;
  ASSERT_FALSE(DecodeDescriptorResidual(code, predicted, &decoded));
  EXPECT_EQ(cv::norm(decoded, descriptors, cv::NORM_HAMMING), 0.0);
}

TEST(DescriptorCoding, ShortDescriptorsAndNoKeyPoints) {
  const cv::Mat predicted = RandomDescriptors(3, 16, 3);
  cv::Mat descriptors = predicted.clone();
  descriptors.at<uint8_t>(0, 15) ^= 0x40;  // bit 126
  const std::vector<uint8_t> code = EncodeDescriptorResidual(descriptors, predicted);
  EXPECT_EQ(code, (std::vector<uint8_t>{16, 1, 126, 0, 0}));
  cv::Mat decoded;
  ASSERT_FALSE(DecodeDescriptorResidual(code, predicted, &decoded));
  EXPECT_EQ(cv::norm(decoded, descriptors, cv::NORM_HAMMING), 0.0);
  EXPECT_FALSE(CheckDescriptorResidual(EncodeDescriptorResidual(cv::Mat(0, 32, CV_8U), cv::Mat(0, 32, CV_8U)), 0));
}

TEST(DescriptorCoding, DamagedCodesAreRefusedWithAReason) {
  const cv::Mat predicted = RandomDescriptors(2, 32, 4);
  cv::Mat descriptors = predicted.clone();
  descriptors.at<uint8_t>(0, 1) ^= 0x06;  // bits 9, 10
  const std::vector<uint8_t> code = EncodeDescriptorResidual(descriptors, predicted);
  ASSERT_EQ(code, (std::vector<uint8_t>{32, 2, 9, 10, 0}));
  EXPECT_TRUE(CheckDescriptorResidual(code, 3));               // fewer key-points coded
  EXPECT_TRUE(CheckDescriptorResidual(code, 1));               // bytes left over
  EXPECT_TRUE(CheckDescriptorResidual({}, 0));                 // no length byte
  EXPECT_TRUE(CheckDescriptorResidual({12, 0}, 1));            // 12-byte descriptors
  EXPECT_TRUE(CheckDescriptorResidual({32, 2, 10, 9, 0}, 2));  // positions not increasing
  EXPECT_TRUE(CheckDescriptorResidual({8, 1, 64}, 1));         // bit beyond 8 bytes
  EXPECT_TRUE(CheckDescriptorResidual({8, 255, 1, 2, 3}, 1));  // verbatim cut short
  cv::Mat decoded;
  EXPECT_TRUE(DecodeDescriptorResidual(code, RandomDescriptors(2, 16, 5), &decoded));  // other length predicted
  EXPECT_THROW(EncodeDescriptorResidual(descriptors, RandomDescriptors(3, 32, 6)), std::invalid_argument);
}

}  // namespace
}  // namespace retrace
