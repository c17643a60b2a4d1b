// Shift search by Cholesky attempts, then Spectra's Lanczos on the inverse.
#include "certify/min_eigenpair.h"

#include <Spectra/SymEigsSolver.h>
#include <Eigen/CholmodSupport>

#include <random>
#include <stdexcept>
#include <string>

namespace certislam::certify {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;
using Cholesky = Eigen::CholmodDecomposition<SparseMatrix, Eigen::Lower>;

void Require(bool ok, const std::string& field, double value, const std::string& rule) {
    if (!ok) {
        throw std::invalid_argument("MinEigenpairConfig." + field + " = " + std::to_string(value) +
                                    ": must be " + rule);
    }
}

/// y = (S - sigma I)^{-1} x through a factorization, in Spectra's operator interface.
class InverseOperator {
  public:
    using Scalar = double;
    InverseOperator(const Cholesky& factor, Eigen::Index size) : factor_(factor), size_(size) {}
    Eigen::Index rows() const { return size_; }
    Eigen::Index cols() const { return size_; }
    void perform_op(const double* x_in, double* y_out) const {
        Eigen::Map<const Eigen::VectorXd> x(x_in, size_);
        Eigen::Map<Eigen::VectorXd> y(y_out, size_);
        y = factor_.solve(x);
    }

  private:
    const Cholesky& factor_;
    Eigen::Index size_;
};

/// Factorizes S - sigma I for sigma = -initial_shift * growth^k until it succeeds.
bool FindShift(const SparseMatrix& S, const MinEigenpairConfig& config, Cholesky* factor,
               MinEigenpairResult* result) {
    factor->cholmod().print = 0;  // a failed attempt is expected, not worth a warning
    // LL^T only: Eigen's automatic mode keeps a simplicial LDL^T, which "succeeds" on indefinite
    // matrices and would make every shift look valid. Simplicial or supernodal is CHOLMOD's own
    // choice (supernodal when flops / nnz(L) >= Common.supernodal_switch, 40): Debian's ATLAS runs
    // supernodal solves through its reference trsv, so on sparse factors the Lanczos solves are
    // faster simplicial, while dense factors (torus3D) stay supernodal.
    // Simplicial LL^T reports a pivot <= 0 as not positive definite only with dbound = 0 (the
    // default; a positive dbound would clamp it and accept indefinite matrices).
    factor->setMode(Eigen::CholmodSimplicialLLt);  // final_ll: LL^T in both forms
    factor->cholmod().supernodal = CHOLMOD_AUTO;
    factor->cholmod().dbound = 0.0;
    factor->analyzePattern(S);
    double magnitude = config.initial_shift;
    for (int k = 0; k < config.max_shift_attempts; ++k) {
        result->shift_attempts = k + 1;
        factor->setShift(magnitude);
        factor->factorize(S);
        if (factor->info() == Eigen::Success) {
            result->shift = -magnitude;
            return true;
        }
        magnitude *= config.shift_growth;
    }
    return false;
}

}  // namespace

void MinEigenpairConfig::Validate() const {
    Require(initial_shift > 0.0, "initial_shift", initial_shift, "> 0");
    Require(shift_growth > 1.0, "shift_growth", shift_growth, "> 1");
    Require(max_shift_attempts > 0, "max_shift_attempts", max_shift_attempts, "> 0");
    Require(tolerance > 0.0, "tolerance", tolerance, "> 0");
    Require(max_iterations > 0, "max_iterations", max_iterations, "> 0");
    Require(subspace >= 3, "subspace", subspace, ">= 3");
}

MinEigenpairResult SmallestEigenpair(const SparseMatrix& S, const MinEigenpairConfig& config) {
    config.Validate();
    MinEigenpairResult result;
    const Eigen::Index size = S.rows();
    Cholesky factor;
    if (!FindShift(S, config, &factor, &result)) {
        result.status = MinEigenpairResult::Status::kNoShiftFound;
        return result;
    }
    InverseOperator op(factor, size);
    const Eigen::Index ncv = std::min<Eigen::Index>(config.subspace, size);
    Spectra::SymEigsSolver<InverseOperator> eigs(op, 1, ncv);
    std::mt19937_64 rng(config.seed);
    std::normal_distribution<double> normal;
    Eigen::VectorXd start(size);
    for (Eigen::Index i = 0; i < size; ++i) start[i] = normal(rng);
    eigs.init(start.data());
    eigs.compute(Spectra::SortRule::LargestAlge, config.max_iterations, config.tolerance);
    result.iterations = static_cast<int>(eigs.num_iterations());
    if (eigs.info() != Spectra::CompInfo::Successful) {
        result.status = MinEigenpairResult::Status::kNotConverged;
        return result;
    }
    result.vector = eigs.eigenvectors(1).col(0).normalized();
    const Eigen::VectorXd Sv = S * result.vector;
    result.lambda = result.vector.dot(Sv);
    result.residual = (Sv - result.lambda * result.vector).norm();
    result.status = MinEigenpairResult::Status::kConverged;
    return result;
}

}  // namespace certislam::certify
