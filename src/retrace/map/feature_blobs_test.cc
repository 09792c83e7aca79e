#include "retrace/map/feature_blobs.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

std::vector<FeatureObservation> SomeFeatures() {
  std::vector<FeatureObservation> features;
  // Out of order, with ids far apart and close together, positions across a 1226x370 key-image.
  for (const feature_t id : {feature_t{70000}, feature_t{3}, feature_t{70001}, feature_t{123456789012}, feature_t{0}}) {
    FeatureObservation f;
    f.feature_id = id;
    f.position = Vector2d(1225.123456 * ((id % 7) + 1) / 7.0, 369.98765 * ((id % 5) + 1) / 5.0);
    features.push_back(f);
  }
  features[1].patch = cv::Mat(5, 5, CV_8UC1);
  cv::randu(features[1].patch, 0, 256);
  return features;
}

TEST(FeatureBlobs, FeaturesRoundTripSortedByIdWithFloatPositionsAndExactPatches) {
  const std::vector<FeatureObservation> written = SomeFeatures();
  std::vector<FeatureObservation> read;
  ASSERT_FALSE(DecodeFeatures(EncodeFeatures(written), &read));
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 1; i < read.size(); ++i) EXPECT_LT(read[i - 1].feature_id, read[i].feature_id);
  for (const FeatureObservation& w : written) {
    const auto r = std::find_if(read.begin(), read.end(), [&](const auto& f) { return f.feature_id == w.feature_id; });
    ASSERT_NE(r, read.end());
    // 32-bit floats: exactly the float nearest the position (1e-4 px at 1226 px).
    EXPECT_EQ(r->position.x(), static_cast<double>(static_cast<float>(w.position.x())));
    EXPECT_EQ(r->position.y(), static_cast<double>(static_cast<float>(w.position.y())));
    EXPECT_NEAR(r->position.x(), w.position.x(), 1e-4);
    ASSERT_EQ(r->patch.size(), w.patch.size());
    if (!w.patch.empty()) {
      EXPECT_EQ(cv::norm(r->patch, w.patch, cv::NORM_INF), 0.0);
    }
  }
  std::vector<FeatureObservation> none;
  EXPECT_TRUE(EncodeFeatures({}).empty());
  EXPECT_FALSE(DecodeFeatures({}, &none));
  EXPECT_TRUE(none.empty());
}

TEST(FeatureBlobs, AKeyImagesFeaturesCostAboutTenBytesEach) {
  // Ids as teach gives them: increasing with gaps of a few (features of one key-image were born close in time).
  std::vector<FeatureObservation> features;
  for (int i = 0; i < 236; ++i) {
    FeatureObservation f;
    f.feature_id = 52000 + 3 * i;
    f.position = Vector2d(5.2 * i, 1.5 * i);
    features.push_back(f);
  }
  // One byte of id delta, 8 of position, one of (no) patch: against 28 bytes in a table row.
  EXPECT_EQ(EncodeFeatures(features).size(), 236u * 10 + 2);  // the first id takes 3 bytes
  std::vector<ArcPoint> points;
  for (int i = 0; i < 150; ++i) points.push_back({52000 + 3 * i, Vector3d(0.1 * i, -0.2, 30.0 + i)});
  EXPECT_EQ(EncodeArcPoints(points).size(), 150u * 13 + 2);  // against 42 bytes in a table row
}

TEST(FeatureBlobs, ArcPointsRoundTrip) {
  std::vector<ArcPoint> written = {{9, Vector3d(0.5, -1.25, 31.0)}, {2, Vector3d(-1e5, 3.0, 1e-7)}};
  std::vector<ArcPoint> read;
  ASSERT_FALSE(DecodeArcPoints(EncodeArcPoints(written), &read));
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[0].feature_id, 2);
  EXPECT_EQ(read[1].feature_id, 9);
  EXPECT_EQ(read[1].point_in_from, Vector3d(0.5, -1.25, 31.0));  // representable exactly
  EXPECT_NEAR(read[0].point_in_from.z(), 1e-7, 1e-14);
}

TEST(FeatureBlobs, WhatCannotBeStoredIsRefused) {
  std::vector<FeatureObservation> twice = SomeFeatures();
  twice[0].feature_id = twice[2].feature_id;
  EXPECT_THROW(EncodeFeatures(twice), std::invalid_argument);
  std::vector<FeatureObservation> negative = SomeFeatures();
  negative[0].feature_id = -5;
  EXPECT_THROW(EncodeFeatures(negative), std::invalid_argument);
  std::vector<FeatureObservation> far = SomeFeatures();
  far[0].position.x() = 1e300;
  EXPECT_THROW(EncodeFeatures(far), std::invalid_argument);
  std::vector<FeatureObservation> color = SomeFeatures();
  color[0].patch = cv::Mat(3, 3, CV_8UC3);
  EXPECT_THROW(EncodeFeatures(color), std::invalid_argument);
  EXPECT_THROW(EncodeArcPoints({{1, Vector3d(0, 0, std::nan(""))}}), std::invalid_argument);
  EXPECT_THROW(EncodeArcPoints({{1, Vector3d::Zero()}, {1, Vector3d::Ones()}}), std::invalid_argument);
}

TEST(FeatureBlobs, DamagedBytesAreReportedNeverReadPastTheirEnd) {
  const std::vector<uint8_t> features = EncodeFeatures(SomeFeatures());
  const std::vector<uint8_t> points = EncodeArcPoints({{4, Vector3d(1, 2, 3)}, {7, Vector3d(4, 5, 6)}});
  // Every truncation but at an entry's end is a fault (an entry's end reads as fewer entries, which the map's
  // checksum finds).
  std::vector<FeatureObservation> read_features;
  int faults = 0;
  for (size_t size = 0; size < features.size(); ++size) {
    faults += DecodeFeatures(std::vector<uint8_t>(features.begin(), features.begin() + size), &read_features) ? 1 : 0;
  }
  EXPECT_EQ(faults, static_cast<int>(features.size()) - 5);  // 5 features: sizes 0 and four entry ends decode
  std::vector<ArcPoint> read_points;
  for (size_t size = 1; size < points.size(); ++size) {
    if (size == 13) continue;  // the first point's end
    EXPECT_TRUE(DecodeArcPoints(std::vector<uint8_t>(points.begin(), points.begin() + size), &read_points)) << size;
  }
  // A repeated id (a zero delta after the first), a non-finite coordinate, an overlong varint.
  std::vector<uint8_t> repeated = points;
  repeated[13] = 0;
  EXPECT_TRUE(DecodeArcPoints(repeated, &read_points));
  std::vector<uint8_t> not_finite = points;
  for (int i = 1; i <= 4; ++i) not_finite[i] = 0xFF;  // a NaN x
  const auto fault = DecodeArcPoints(not_finite, &read_points);
  ASSERT_TRUE(fault);
  EXPECT_NE(fault->find("not finite"), std::string::npos) << *fault;
  EXPECT_TRUE(DecodeArcPoints(std::vector<uint8_t>(11, 0xFF), &read_points));
}

}  // namespace
}  // namespace retrace
