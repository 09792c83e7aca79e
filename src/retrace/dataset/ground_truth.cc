#include "retrace/dataset/ground_truth.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>

#include <Eigen/SVD>
#include <fmt/format.h>

#include "retrace/dataset/text_io.h"
#include "retrace/util/error.h"

namespace retrace {
namespace {

// Largest tolerated deviation of a file's rotation from orthonormality (max |R^T R - I| entry). KITTI's rounding to
// 7 digits gives ~1e-7; anything beyond 1e-3 is not a rotation with rounding but a wrong matrix.
constexpr double kMaxRotationDeviation = 1e-3;
// Largest tolerated deviation of a file's quaternion norm from 1.
constexpr double kMaxQuaternionNormDeviation = 1e-2;

Matrix3d CheckedRotation(const Matrix3d& m, const std::string& file, size_t line_number) {
  const double deviation = (m.transpose() * m - Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(deviation <= kMaxRotationDeviation) || !(m.determinant() > 0)) {
    throw InputError(file, fmt::format("line {}: the 3x3 part is not a rotation (|R^T R - I| = {:.3g}, det = {:.3g})",
                                       line_number, deviation, m.determinant()));
  }
  return NearestRotation(m);
}

Matrix3d CheckedQuaternion(double w, double x, double y, double z, const std::string& file, size_t line_number) {
  Eigen::Quaterniond q(w, x, y, z);
  const double norm = q.norm();
  if (!(std::abs(norm - 1.0) <= kMaxQuaternionNormDeviation)) {
    throw InputError(file, fmt::format("line {}: quaternion norm {:.6g} is not 1", line_number, norm));
  }
  return q.normalized().toRotationMatrix();
}

void CheckWritten(std::ofstream& out, const std::filesystem::path& path) {
  out.flush();
  if (!out) throw InputError(path.string(), "cannot write the file");
}

}  // namespace

Matrix3d NearestRotation(const Matrix3d& m) {
  // Near a rotation, Newton–Schulz iterations R <- R (3 I - R^T R) / 2 converge quadratically to the orthogonal polar
  // factor (the nearest rotation) and leave an exact rotation exactly unchanged, which SVD does not (it returns
  // 1 - 8e-16 on the diagonal of an identity). Far from a rotation, the SVD projection U diag(1, 1, det) V^T.
  Matrix3d r = m;
  for (int iteration = 0; iteration < 20; ++iteration) {
    const Matrix3d error = r.transpose() * r - Matrix3d::Identity();
    const double deviation = error.cwiseAbs().maxCoeff();
    if (deviation > 0.1 || !std::isfinite(deviation)) break;
    if (deviation == 0.0) return r;
    r = r * (Matrix3d::Identity() - 0.5 * error);
    if (deviation < 1e-15 && r.determinant() > 0) return r;
  }
  Eigen::JacobiSVD<Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Matrix3d d = Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

std::vector<TimedPose> ReadKittiPoses(const std::filesystem::path& poses_txt,
                                      const std::filesystem::path& times_txt) {
  const std::string file = poses_txt.string();
  std::vector<TimedPose> poses;
  for (const TextLine& line : ReadTextLines(poses_txt)) {
    const std::vector<double> v = ParseNumbers(line, ' ', file);
    if (v.size() != 12) {
      throw InputError(file, fmt::format("line {}: expected 12 numbers (row-major 3x4 [R|t]), found {}", line.number,
                                         v.size()));
    }
    Matrix3d r;
    r << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    TimedPose pose;
    pose.timestamp = static_cast<double>(poses.size());
    pose.world_from_cam = Rigid3d(CheckedRotation(r, file, line.number), Vector3d(v[3], v[7], v[11]));
    poses.push_back(pose);
  }
  CheckInput(!poses.empty(), file, "no poses in the file");
  if (!times_txt.empty()) {
    const std::vector<double> times = ReadTimestamps(times_txt);
    if (times.size() != poses.size()) {
      throw InputError(times_txt.string(), fmt::format("{} timestamps but {} poses in {}", times.size(),
                                                       poses.size(), file));
    }
    for (size_t i = 0; i < poses.size(); ++i) poses[i].timestamp = times[i];
  }
  return poses;
}

std::vector<TimedPose> ReadTumPoses(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::vector<TimedPose> poses;
  for (const TextLine& line : ReadTextLines(path, /*skip_comments_and_empty=*/true)) {
    const std::vector<double> v = ParseNumbers(line, ' ', file);
    if (v.size() != 8) {
      throw InputError(file, fmt::format("line {}: expected 8 numbers (timestamp tx ty tz qx qy qz qw), found {}",
                                         line.number, v.size()));
    }
    TimedPose pose;
    pose.timestamp = v[0];
    pose.world_from_cam = Rigid3d(CheckedQuaternion(v[7], v[4], v[5], v[6], file, line.number),
                                  Vector3d(v[1], v[2], v[3]));
    poses.push_back(pose);
  }
  CheckInput(!poses.empty(), file, "no poses in the file");
  return poses;
}

std::vector<TimedPose> ReadEurocPoses(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::vector<TimedPose> poses;
  for (const TextLine& line : ReadTextLines(path, /*skip_comments_and_empty=*/true)) {
    const std::vector<double> v = ParseNumbers(line, ',', file);
    if (v.size() < 8) {
      throw InputError(file, fmt::format("line {}: expected at least 8 comma-separated numbers (timestamp [ns], "
                                         "p xyz, q wxyz), found {}",
                                         line.number, v.size()));
    }
    TimedPose pose;
    pose.timestamp = v[0] * 1e-9;
    pose.world_from_cam = Rigid3d(CheckedQuaternion(v[4], v[5], v[6], v[7], file, line.number),
                                  Vector3d(v[1], v[2], v[3]));
    poses.push_back(pose);
  }
  CheckInput(!poses.empty(), file, "no poses in the file");
  return poses;
}

void WriteKittiPoses(const std::filesystem::path& poses_txt, const std::vector<TimedPose>& poses,
                     const std::filesystem::path& times_txt) {
  std::ofstream out(poses_txt);
  CheckInput(out.is_open(), poses_txt.string(), "cannot open the file for writing");
  for (const TimedPose& pose : poses) out << FormatKittiPose(pose.world_from_cam) << '\n';
  CheckWritten(out, poses_txt);
  if (times_txt.empty()) return;
  std::ofstream times(times_txt);
  CheckInput(times.is_open(), times_txt.string(), "cannot open the file for writing");
  for (const TimedPose& pose : poses) times << fmt::format("{}", pose.timestamp) << '\n';
  CheckWritten(times, times_txt);
}

void WriteTumPoses(const std::filesystem::path& path, const std::vector<TimedPose>& poses) {
  std::ofstream out(path);
  CheckInput(out.is_open(), path.string(), "cannot open the file for writing");
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const TimedPose& pose : poses) {
    const Eigen::Quaterniond q(pose.world_from_cam.rotation);
    const Vector3d& t = pose.world_from_cam.translation;
    out << fmt::format("{} {} {} {} {} {} {} {}\n", pose.timestamp, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
  }
  CheckWritten(out, path);
}

std::optional<Rigid3d> InterpolatePose(const std::vector<TimedPose>& poses, double t) {
  if (poses.empty() || !(t >= poses.front().timestamp) || !(t <= poses.back().timestamp)) return std::nullopt;
  // First pose with timestamp > t; the bracket is [it - 1, it].
  const auto it = std::upper_bound(poses.begin(), poses.end(), t,
                                   [](double value, const TimedPose& pose) { return value < pose.timestamp; });
  if (it == poses.end()) return poses.back().world_from_cam;  // t == last timestamp
  const TimedPose& a = *(it - 1);
  const TimedPose& b = *it;
  const double span = b.timestamp - a.timestamp;
  const double s = span > 0 ? (t - a.timestamp) / span : 0.0;
  const Eigen::Quaterniond qa(a.world_from_cam.rotation);
  const Eigen::Quaterniond qb(b.world_from_cam.rotation);
  // Eigen's slerp takes the shorter arc (it flips the sign of qb when qa.qb < 0).
  const Eigen::Quaterniond q = qa.slerp(s, qb);
  return Rigid3d(q.toRotationMatrix(),
                 (1.0 - s) * a.world_from_cam.translation + s * b.world_from_cam.translation);
}

double TrajectoryLength(const std::vector<TimedPose>& poses) {
  double length = 0;
  for (size_t i = 1; i < poses.size(); ++i) {
    length += (poses[i].world_from_cam.translation - poses[i - 1].world_from_cam.translation).norm();
  }
  return length;
}

}  // namespace retrace
