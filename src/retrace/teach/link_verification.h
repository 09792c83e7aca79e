#pragma once

// Verifying a link that wide-baseline matching made between two key-images (loop closing, gap recovery; design §5).
//
// One pair of images is not enough evidence: in a town of look-alike facades and identical zebra crossings, the
// last key-image of a drive matched a key-image 151 m away with 50 inliers and σ_p 0.29 px (a plausible forward
// motion over the crossing), and repeat then tracked along that non-existent arc. What a false link cannot
// reproduce is the motion to the images around it: the link A -> B followed by the tracked arc B -> S (to the next
// key-image on the drive) predicts where A is seen from S, and an independent matching of A with S must measure
// that motion. Likewise the tracked arc P -> A followed by the link predicts the matching of P with B.
//
//          link W_AB               W_AB: x_B = R_AB x_A + λ t_AB        (unit t, unknown scale λ > 0)
//     A ──────────────> B          W_BS: x_S = R_BS x_B + μ t_BS        (tracked, trusted)
//      ╲                │
//       ╲ matched W_AS  │ W_BS     composed: R_AS = R_BS R_AB,
//        ╲              v                    t_AS ∝ λ R_BS t_AB + μ t_BS   for some λ, μ >= 0
//         ──────────>   S
//
// Each geometry has its own unit of length, so the composed translation direction is only known to lie on the
// shorter great-circle arc between R_BS t_AB and t_BS; the measured direction must lie near that arc, and the
// measured rotation near R_BS R_AB. A look-alike place that fools one pair rarely fools the pair one arc further
// on, where the camera has moved past (or away from) the repeated structure.
//
// A witness confirms the link (it relates and agrees), contradicts it (it relates and disagrees), or says nothing
// (it does not relate: wide-baseline matching has a limited reach). teacher.h says which witnesses a link needs.

#include "retrace/util/types.h"

namespace retrace {

// How far a measured motion X -> Z lies from the composition of X -> Y and Y -> Z.
struct MotionAgreement {
  // Angle between the measured rotation and the composed one, degrees.
  double rotation_deg = 0.0;
  // Angle between the measured translation direction and the nearest direction the composition allows for any
  // positive scales of its two parts, degrees.
  double direction_deg = 0.0;
};

// Compares `z_from_x` with the composition of `y_from_x` and `z_from_y`, each with unit (or any positive-length)
// translation in its own scale. Translations of zero length are treated as unknown directions (0 disagreement).
MotionAgreement CompareComposedMotion(const Rigid3d& y_from_x, const Rigid3d& z_from_y, const Rigid3d& z_from_x);

// The same when the ratio of the two parts' scales is known: `scale` (> 0) is the length of Y -> Z over that of
// X -> Y (the relative scale at Y, design §3.3, from the depths of features reconstructed by both geometries). The
// composition then allows one translation direction, λ R_ZY t_YX + μ t_ZY with μ / λ = scale (unit t_YX, t_ZY), and
// the measured one must lie near it, not merely near the arc: a link whose direction is wrong also misplaces the
// points it reconstructs, and their depths at Y disagree with the witness's (kitti07 at 320 px, every 3rd frame:
// the gap arc of frames 81-84, 20 degrees off, lies 0.3 degrees from the arc its witness allows, 12.9 degrees from
// the composed direction at the scale their shared features give).
MotionAgreement CompareComposedMotion(const Rigid3d& y_from_x, const Rigid3d& z_from_y, const Rigid3d& z_from_x,
                                      double scale);

// Whether a link X -> Y continues the drive: a link says that a robot leaving X arrives at Y, so Y lies ahead of X in
// the direction the drive travelled at X, and X behind Y in the direction it travelled at Y. `x_from_p` is the tracked
// arc into X (P -> X: the camera travelled from P's centre to X's), `y_from_x` the link, `s_from_y` the tracked arc
// out of Y (Y -> S). Returns the cosines of the angles between the step X -> Y and the direction of travel at X
// (`at_from`) and at Y (`at_to`); positive: the link moves forward there. A cosine whose arc is not given (null) or
// has no direction is NaN. The drive's own motion measures the direction of travel, so this holds for any camera
// (forward-looking or omnidirectional) and needs no threshold but the sign: a loop link to a key-image the drive
// passed a few metres back (kitti07's frames 0-39: the last key-image, frame 39, to key-image 1, frame 25, 4.8 m
// behind it, 111 inliers, every witness agreeing since "back, then forward" composes into any direction between
// them) has cosines near -1.
struct LinkDirection {
  double at_from = 0.0;
  double at_to = 0.0;
};
LinkDirection LinkDirectionOfTravel(const Rigid3d* x_from_p, const Rigid3d& y_from_x, const Rigid3d* s_from_y);

}  // namespace retrace
