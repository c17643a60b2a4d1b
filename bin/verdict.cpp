// Lower-case names of the certificate's verdicts and paths (see verdict.h).
#include "bin/verdict.h"

#include "actors/convert.h"

namespace certislam::bin {

std::string VerdictName(v1::CertificateVerdict verdict) { return actors::VerdictName(verdict); }

std::string CertificatePathName(v1::CertificatePath path) {
    switch (path) {
        case v1::CERTIFICATE_PATH_CENTRALISED:
            return "centralised";
        case v1::CERTIFICATE_PATH_DISTRIBUTED:
            return "distributed";
        case v1::CERTIFICATE_PATH_FALLBACK:
            return "fallback";
        default:
            return "none";
    }
}

}  // namespace certislam::bin
