// The certificate's report on the wire (actors/convert.h): verdict and quantities out, and the one
// spelling of a received verdict. Apart from the decoders, which the fuzzers build alone.
#include "actors/convert.h"

namespace certislam::actors {

v1::CertificateVerdict VerdictOf(certify::CertificateResult::Status status) {
    using S = certify::CertificateResult::Status;
    switch (status) {
        case S::kCertified:
            return v1::CERTIFICATE_VERDICT_CERTIFIED;
        case S::kNotOptimal:
            return v1::CERTIFICATE_VERDICT_NOT_CERTIFIED;
        case S::kNotCritical:
            return v1::CERTIFICATE_VERDICT_NOT_CRITICAL;
        case S::kInconclusive:
            return v1::CERTIFICATE_VERDICT_INCONCLUSIVE;
    }
    return v1::CERTIFICATE_VERDICT_UNSPECIFIED;
}

v1::CertificateReport ToProto(const certify::CertificateResult& result, std::uint32_t rank) {
    v1::CertificateReport out;
    out.set_verdict(VerdictOf(result.status));
    out.set_lambda_min(result.lambda_min);
    out.set_eps_tolerance(result.eta);
    out.set_suboptimality_bound(result.suboptimality_bound);
    out.set_duality_gap(result.duality_gap);
    out.set_objective(result.objective);
    out.set_rank_r(rank);
    out.set_has_bound(result.has_bound);
    out.set_lower_bound(result.lower_bound);
    out.set_relative_suboptimality_bound(result.relative_suboptimality_bound);
    out.set_dual_value(result.dual_value);
    out.set_gradient_norm(result.gradient_norm);
    out.set_gradient_tolerance(result.gradient_tolerance);
    out.set_reason(result.reason);
    return out;
}

std::string VerdictName(v1::CertificateVerdict verdict) {
    using S = certify::CertificateResult::Status;
    switch (verdict) {
        case v1::CERTIFICATE_VERDICT_CERTIFIED:
            return certify::VerdictName(S::kCertified);
        case v1::CERTIFICATE_VERDICT_NOT_CERTIFIED:
            return certify::VerdictName(S::kNotOptimal);
        case v1::CERTIFICATE_VERDICT_NOT_CRITICAL:
            return certify::VerdictName(S::kNotCritical);
        case v1::CERTIFICATE_VERDICT_INCONCLUSIVE:
            return certify::VerdictName(S::kInconclusive);
        default:
            return "none";
    }
}

}  // namespace certislam::actors
