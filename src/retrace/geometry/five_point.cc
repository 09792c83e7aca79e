#include "retrace/geometry/five_point.h"

#include <array>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>

namespace retrace {
namespace {

// Polynomials in the null-space coordinates (x, y, z) of E = x X + y Y + z Z + W, as coefficient arrays over fixed
// monomial lists. The cubic list starts with the 10 monomials of degree 3 (eliminated by Gauss-Jordan) followed by
// the 10 of degree ≤ 2, which are the basis of the quotient ring, in the order of kQuadratic.
struct Exponents {
  int x, y, z;
};

constexpr Exponents kLinear[4] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
constexpr Exponents kQuadratic[10] = {{2, 0, 0}, {1, 1, 0}, {0, 2, 0}, {1, 0, 1}, {0, 1, 1},
                                      {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
constexpr Exponents kCubic[20] = {{3, 0, 0}, {2, 1, 0}, {1, 2, 0}, {0, 3, 0}, {2, 0, 1}, {1, 1, 1}, {0, 2, 1},
                                  {1, 0, 2}, {0, 1, 2}, {0, 0, 3}, {2, 0, 0}, {1, 1, 0}, {0, 2, 0}, {1, 0, 1},
                                  {0, 1, 1}, {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}};
constexpr int kNumCubicMonomials = 10;  // degree-3 monomials at the front of kCubic
constexpr int kBasisSize = 10;          // degree ≤ 2 monomials: kCubic[10 + j] == kQuadratic[j]

constexpr bool BasisFollowsCubicMonomials() {
  for (int j = 0; j < kBasisSize; ++j) {
    const Exponents& a = kCubic[kNumCubicMonomials + j];
    if (a.x != kQuadratic[j].x || a.y != kQuadratic[j].y || a.z != kQuadratic[j].z) return false;
    if (kCubic[j].x + kCubic[j].y + kCubic[j].z != 3) return false;
  }
  return true;
}
static_assert(BasisFollowsCubicMonomials(), "kCubic = 10 cubic monomials, then kQuadratic");

template <size_t N>
constexpr int IndexOf(const Exponents (&list)[N], int x, int y, int z) {
  for (size_t i = 0; i < N; ++i) {
    if (list[i].x == x && list[i].y == y && list[i].z == z) return static_cast<int>(i);
  }
  return -1;
}

// Where the product of two monomials lands: kLinear x kLinear -> kQuadratic, kQuadratic x kLinear -> kCubic.
struct ProductIndices {
  int linear_linear[4][4];
  int quadratic_linear[10][4];
};

constexpr ProductIndices MakeProductIndices() {
  ProductIndices p{};
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      p.linear_linear[i][j] = IndexOf(kQuadratic, kLinear[i].x + kLinear[j].x, kLinear[i].y + kLinear[j].y,
                                      kLinear[i].z + kLinear[j].z);
    }
  }
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 4; ++j) {
      p.quadratic_linear[i][j] = IndexOf(kCubic, kQuadratic[i].x + kLinear[j].x, kQuadratic[i].y + kLinear[j].y,
                                         kQuadratic[i].z + kLinear[j].z);
    }
  }
  return p;
}

constexpr ProductIndices kProducts = MakeProductIndices();

using Linear = std::array<double, 4>;
using Quadratic = std::array<double, 10>;
using Cubic = std::array<double, 20>;

// out += a * b
void AddProduct(const Linear& a, const Linear& b, Quadratic* out) {
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) (*out)[kProducts.linear_linear[i][j]] += a[i] * b[j];
  }
}

void AddProduct(const Quadratic& a, const Linear& b, double scale, Cubic* out) {
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 4; ++j) (*out)[kProducts.quadratic_linear[i][j]] += scale * a[i] * b[j];
  }
}

Quadratic Product(const Linear& a, const Linear& b) {
  Quadratic q{};
  AddProduct(a, b, &q);
  return q;
}

}  // namespace

void SolveEssentialFivePoint(const Vector3d bearings_a[5], const Vector3d bearings_b[5],
                             std::vector<Matrix3d>* essentials) {
  // 1. f_Bᵀ E f_A = Σ_ij b_i E_ij a_j = 0: one row per correspondence over the 9 entries of E (row-major). The null
  //    space is the orthogonal complement of the rows, read from a rank-revealing QR of the 9 x 5 transpose.
  Eigen::Matrix<double, 9, 5> rows_transposed;
  for (int k = 0; k < 5; ++k) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) rows_transposed(3 * i + j, k) = bearings_b[k][i] * bearings_a[k][j];
    }
  }
  if (!rows_transposed.allFinite()) return;
  const Eigen::ColPivHouseholderQR<Eigen::Matrix<double, 9, 5>> qr(rows_transposed);
  if (qr.rank() < 5) return;
  const Eigen::Matrix<double, 9, 9> q = qr.householderQ();
  const Eigen::Matrix<double, 9, 4> null_space = q.rightCols<4>();

  // E_ij = x X_ij + y Y_ij + z Z_ij + W_ij as a linear polynomial per entry.
  Linear e[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      for (int b = 0; b < 4; ++b) e[i][j][b] = null_space(3 * i + j, b);
    }
  }

  // 2. The 10 cubic constraints. Trace constraint (Nistér 2004, eq. (5)) written as (E Eᵀ - ½ trace(E Eᵀ) I) E = 0.
  Quadratic e_et[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int j = i; j < 3; ++j) {
      e_et[i][j] = Quadratic{};
      for (int k = 0; k < 3; ++k) AddProduct(e[i][k], e[j][k], &e_et[i][j]);
      e_et[j][i] = e_et[i][j];
    }
  }
  Quadratic half_trace{};
  for (int m = 0; m < 10; ++m) half_trace[m] = 0.5 * (e_et[0][0][m] + e_et[1][1][m] + e_et[2][2][m]);
  Quadratic lambda[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      lambda[i][j] = e_et[i][j];
      if (i == j) {
        for (int m = 0; m < 10; ++m) lambda[i][j][m] -= half_trace[m];
      }
    }
  }
  Eigen::Matrix<double, 10, 20> constraints = Eigen::Matrix<double, 10, 20>::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      Cubic c{};
      for (int k = 0; k < 3; ++k) AddProduct(lambda[i][k], e[k][j], 1.0, &c);
      for (int m = 0; m < 20; ++m) constraints(3 * i + j, m) = c[m];
    }
  }
  // det(E) = 0 by cofactor expansion along the first row.
  {
    Cubic det{};
    AddProduct(Product(e[1][1], e[2][2]), e[0][0], 1.0, &det);
    AddProduct(Product(e[1][2], e[2][1]), e[0][0], -1.0, &det);
    AddProduct(Product(e[1][2], e[2][0]), e[0][1], 1.0, &det);
    AddProduct(Product(e[1][0], e[2][2]), e[0][1], -1.0, &det);
    AddProduct(Product(e[1][0], e[2][1]), e[0][2], 1.0, &det);
    AddProduct(Product(e[1][1], e[2][0]), e[0][2], -1.0, &det);
    for (int m = 0; m < 20; ++m) constraints(9, m) = det[m];
  }

  // 3. Gauss-Jordan on the cubic monomials: cubic_r + Σ_j reduced(r, j) basis_j = 0 on the solutions.
  const Eigen::Matrix<double, 10, 10> cubic_part = constraints.leftCols<kNumCubicMonomials>();
  const Eigen::Matrix<double, 10, 10> basis_part = constraints.rightCols<kBasisSize>();
  const Eigen::Matrix<double, 10, 10> reduced = cubic_part.partialPivLu().solve(basis_part);
  if (!reduced.allFinite()) return;

  // 4. Action matrix of the multiplication by x: x · basis_j is a basis monomial or a reduced cubic monomial, so that
  //    x(s) v(s) = action v(s) with v(s) the basis evaluated at a solution s.
  Eigen::Matrix<double, 10, 10> action = Eigen::Matrix<double, 10, 10>::Zero();
  for (int j = 0; j < kBasisSize; ++j) {
    const Exponents& m = kQuadratic[j];
    const int product = IndexOf(kCubic, m.x + 1, m.y, m.z);
    if (product < kNumCubicMonomials) {
      action.row(j) = -reduced.row(product);
    } else {
      action(j, product - kNumCubicMonomials) = 1.0;
    }
  }
  const Eigen::EigenSolver<Eigen::Matrix<double, 10, 10>> eigen(action, /*computeEigenvectors=*/true);
  if (eigen.info() != Eigen::Success) return;
  constexpr int kX = 6, kY = 7, kZ = 8, kOne = 9;  // positions of x, y, z, 1 in kQuadratic
  for (int s = 0; s < kBasisSize; ++s) {
    // Real eigenvalues are the 1 x 1 blocks of the real Schur form: their imaginary part is exactly zero.
    if (eigen.eigenvalues()[s].imag() != 0.0) continue;
    const Eigen::Matrix<double, 10, 1> v = eigen.eigenvectors().col(s).real();
    if (v[kOne] == 0.0) continue;
    const double x = v[kX] / v[kOne], y = v[kY] / v[kOne], z = v[kZ] / v[kOne];
    const Eigen::Matrix<double, 9, 1> entries =
        x * null_space.col(0) + y * null_space.col(1) + z * null_space.col(2) + null_space.col(3);
    const double norm = entries.norm();
    if (!(norm > 0.0) || !entries.allFinite()) continue;
    Matrix3d essential;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) essential(i, j) = entries(3 * i + j) / norm;
    }
    essentials->push_back(essential);
  }
}

}  // namespace retrace
