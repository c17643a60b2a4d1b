// Register-blocked dense x sparse product (sparse_product.h).
#include "slam/backend/sparse_product.h"

#include "slam/core/check.h"

namespace certislam::slam {
namespace {

// One column of A's nonzeros (begin..end) against V's columns: R accumulators, unrolled.
template <int R>
void Kernel(const double* v, const int* outer, const int* inner, const int* nnz,
            const double* values, Eigen::Index n, double* out) {
    for (Eigen::Index j = 0; j < n; ++j) {
        double acc[R] = {};
        const int begin = outer[j];
        const int end = nnz != nullptr ? begin + nnz[j] : outer[j + 1];
        for (int p = begin; p < end; ++p) {
            const double a = values[p];
            const double* column = v + static_cast<Eigen::Index>(R) * inner[p];
#pragma GCC unroll 8
            for (int c = 0; c < R; ++c) acc[c] += a * column[c];
        }
#pragma GCC unroll 8
        for (int c = 0; c < R; ++c) out[R * j + c] = acc[c];
    }
}

// r = 3 (the staircase's usual rank in 3-D) spelled out: GCC vectorises an array of three
// accumulators as one pair and one single and is then slower than three scalars.
void Kernel3(const double* v, const int* outer, const int* inner, const int* nnz,
             const double* values, Eigen::Index n, double* out) {
    for (Eigen::Index j = 0; j < n; ++j) {
        double a0 = 0.0, a1 = 0.0, a2 = 0.0;
        const int begin = outer[j];
        const int end = nnz != nullptr ? begin + nnz[j] : outer[j + 1];
        for (int p = begin; p < end; ++p) {
            const double a = values[p];
            const double* column = v + 3 * static_cast<Eigen::Index>(inner[p]);
            a0 += a * column[0];
            a1 += a * column[1];
            a2 += a * column[2];
        }
        out[3 * j] = a0;
        out[3 * j + 1] = a1;
        out[3 * j + 2] = a2;
    }
}

}  // namespace

Eigen::MatrixXd DenseTimesSparse(const Eigen::MatrixXd& V, const Eigen::SparseMatrix<double>& A) {
    CERTISLAM_CHECK(V.cols() == A.rows());
    Eigen::MatrixXd out(V.rows(), A.cols());
    const double* v = V.data();
    const int* outer = A.outerIndexPtr();
    const int* inner = A.innerIndexPtr();
    const int* nnz = A.innerNonZeroPtr();  // null when A is compressed
    const double* values = A.valuePtr();
    const Eigen::Index n = A.cols();
    switch (V.rows()) {
        case 1:
            Kernel<1>(v, outer, inner, nnz, values, n, out.data());
            break;
        case 2:
            Kernel<2>(v, outer, inner, nnz, values, n, out.data());
            break;
        case 3:
            Kernel3(v, outer, inner, nnz, values, n, out.data());
            break;
        case 4:
            Kernel<4>(v, outer, inner, nnz, values, n, out.data());
            break;
        case 5:
            Kernel<5>(v, outer, inner, nnz, values, n, out.data());
            break;
        case 6:
            Kernel<6>(v, outer, inner, nnz, values, n, out.data());
            break;
        case 7:
            Kernel<7>(v, outer, inner, nnz, values, n, out.data());
            break;
        case 8:
            Kernel<8>(v, outer, inner, nnz, values, n, out.data());
            break;
        default:
            out = V * A;  // high staircase ranks: rare, Eigen's product
    }
    return out;
}

}  // namespace certislam::slam
