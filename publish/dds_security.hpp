// DDS Security (OMG DDS Security 1.1) for the gateway's participant: the six files of
// publish.dds.security, checked with OpenSSL before Cyclone DDS is given them, and the
// <Security> part of the domain's configuration that names them (docs/guides/secure-dds.md).
//
// Why check them here when Cyclone's builtin plugins check them too: Cyclone says what is wrong
// only in its log and returns "Error" for the participant, without naming the file; a cab's
// commissioning needs "publish.dds.security.certificate …: certificate has expired" at
// `oegw check`, before the cab runs. The checks are those the builtin plugins make at the
// participant's creation: the certificate issued by the identity CA and valid now, the private
// key the certificate's, governance and permissions S/MIME documents signed by the permissions
// CA. What only a remote peer can decide (its own permissions, a handshake) stays Cyclone's.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace oegw::publish {

// In the order of mapping::DdsSecurityConfig::File.
enum DdsSecurityFile : std::size_t {
  kIdentityCa,
  kCertificate,
  kPrivateKey,
  kPermissionsCa,
  kGovernance,
  kPermissions,
  kDdsSecurityFiles
};
inline constexpr std::array<std::string_view, kDdsSecurityFiles> kDdsSecurityKeys = {"identity_ca", "certificate",
                                                                                     "private_key", "permissions_ca",
                                                                                     "governance",  "permissions"};

struct DdsSecuritySettings {
  std::array<std::string, kDdsSecurityFiles> path;  // absolute, or from the working directory
};

// "publish.dds.security.private_key".
[[nodiscard]] std::string dds_security_setting(std::size_t file);

struct DdsSecurityProblem {
  std::size_t file;  // the setting the problem is at
  std::string text;  // "/etc/oegw/dds/gateway.pem: certificate has expired (not after …); expected …"
};

// Every problem of the set, in file order; empty when Cyclone's builtin plugins can take it.
[[nodiscard]] std::vector<DdsSecurityProblem> check_dds_security(const DdsSecuritySettings& s);

// <Security>…</Security> for a Cyclone DDS <Domain>, the files as file: URIs (XML-escaped).
[[nodiscard]] std::string dds_security_xml(const DdsSecuritySettings& s);

}  // namespace oegw::publish
