#include "publish/dds_security.hpp"

#include <openssl/asn1.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/pkcs7.h>
#include <openssl/x509.h>
#include <openssl/x509_vfy.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>

namespace oegw::publish {

namespace {

template <typename T, void (*Free)(T*)>
struct Deleter {
  void operator()(T* p) const { Free(p); }
};
using X509Ptr = std::unique_ptr<X509, Deleter<X509, X509_free>>;
using KeyPtr = std::unique_ptr<EVP_PKEY, Deleter<EVP_PKEY, EVP_PKEY_free>>;
using BioPtr = std::unique_ptr<BIO, Deleter<BIO, BIO_free_all>>;
using StorePtr = std::unique_ptr<X509_STORE, Deleter<X509_STORE, X509_STORE_free>>;
using StoreCtxPtr = std::unique_ptr<X509_STORE_CTX, Deleter<X509_STORE_CTX, X509_STORE_CTX_free>>;
using Pkcs7Ptr = std::unique_ptr<PKCS7, Deleter<PKCS7, PKCS7_free>>;

// OpenSSL's reason for the last failure, its queue emptied ("" when it has none).
std::string openssl_reason() {
  std::string out;
  for (unsigned long e; (e = ERR_get_error()) != 0;) {
    const char* r = ERR_reason_error_string(e);
    if (r != nullptr && out.find(r) == std::string::npos) out += (out.empty() ? "" : ", ") + std::string(r);
  }
  return out;
}

// A regular file this process can read, else why not.
std::string unreadable(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::strerror(errno);
  if (!S_ISREG(st.st_mode)) return "not a regular file";
  if (::access(path.c_str(), R_OK) != 0) return std::strerror(errno);
  return "";
}

// Why a private key's mode is too open, or "": docs/design/threat-model.md asks 0600 — readable by
// its owner (the daemon's user) only. Any group or other bit refuses it, as ssh refuses such a key:
// whoever reads the key is the gateway to every DDS peer until its certificate is revoked.
std::string key_mode_problem(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "";  // unreadable() has said why
  const auto mode = static_cast<unsigned>(st.st_mode & 07777);
  if ((mode & 0077) == 0) return "";
  char octal[8];
  std::snprintf(octal, sizeof octal, "%04o", mode);
  return std::string("mode ") + octal + " lets " + ((mode & 0007) != 0 ? "every user" : "its group") +
         " read or change the private key; expected 0600, owner the daemon's user: chmod 0600 " + path;
}

BioPtr open_file(const std::string& path) { return BioPtr(BIO_new_file(path.c_str(), "r")); }

std::optional<X509Ptr> read_certificate(const std::string& path, std::string& why) {
  BioPtr b = open_file(path);
  X509Ptr c(b ? PEM_read_bio_X509(b.get(), nullptr, nullptr, nullptr) : nullptr);
  if (!c) {
    why = "is no PEM certificate (" + openssl_reason() + ")";
    return std::nullopt;
  }
  return c;
}

// No password prompt: a key for a daemon is stored unencrypted, readable by root only.
int no_password(char*, int, int, void*) { return -1; }

std::string asn1_time(const ASN1_TIME* t) {
  BioPtr b(BIO_new(BIO_s_mem()));
  if (!b || ASN1_TIME_print(b.get(), t) != 1) return "?";
  char* data = nullptr;
  const long n = BIO_get_mem_data(b.get(), &data);
  return std::string(data, static_cast<std::size_t>(n));
}

std::string subject(const X509* c) {
  BioPtr b(BIO_new(BIO_s_mem()));
  if (!b || X509_NAME_print_ex(b.get(), X509_get_subject_name(c), 0, XN_FLAG_RFC2253) < 0) return "?";
  char* data = nullptr;
  const long n = BIO_get_mem_data(b.get(), &data);
  return std::string(data, static_cast<std::size_t>(n));
}

// Why `cert` is not a certificate `ca` issued that is valid now, or "".
std::string verify_certificate(X509* cert, X509* ca) {
  StorePtr store(X509_STORE_new());
  StoreCtxPtr ctx(X509_STORE_CTX_new());
  if (!store || !ctx || X509_STORE_add_cert(store.get(), ca) != 1 ||
      X509_STORE_CTX_init(ctx.get(), store.get(), cert, nullptr) != 1)
    return "cannot be checked (" + openssl_reason() + ")";
  if (X509_verify_cert(ctx.get()) == 1) return "";
  const int e = X509_STORE_CTX_get_error(ctx.get());
  std::string why = X509_verify_cert_error_string(e);
  if (e == X509_V_ERR_CERT_HAS_EXPIRED) why += " (not after " + asn1_time(X509_get0_notAfter(cert)) + ")";
  if (e == X509_V_ERR_CERT_NOT_YET_VALID) why += " (not before " + asn1_time(X509_get0_notBefore(cert)) + ")";
  if (e == X509_V_ERR_UNABLE_TO_GET_ISSUER_CERT_LOCALLY || e == X509_V_ERR_CERT_SIGNATURE_FAILURE ||
      e == X509_V_ERR_UNABLE_TO_GET_ISSUER_CERT)
    why += ": it was not issued by publish.dds.security.identity_ca";
  return why;
}

// Why the S/MIME document at `path` is not one `ca` signed, or "".
std::string verify_document(const std::string& path, X509* ca) {
  BioPtr in = open_file(path);
  BIO* content = nullptr;
  Pkcs7Ptr p7(in ? SMIME_read_PKCS7(in.get(), &content) : nullptr);
  BioPtr content_owner(content);
  if (!p7) return "is no S/MIME signed document (" + openssl_reason() + "); expected `openssl smime -sign` output";
  StorePtr store(X509_STORE_new());
  if (!store || X509_STORE_add_cert(store.get(), ca) != 1) return "cannot be checked (" + openssl_reason() + ")";
  BioPtr out(BIO_new(BIO_s_null()));
  // PKCS7_TEXT: the signed content carries a text/plain MIME header (`openssl smime -sign -text`),
  // as the builtin access control plugin reads it.
  if (PKCS7_verify(p7.get(), nullptr, store.get(), content, out.get(), PKCS7_TEXT) == 1) return "";
  return "is not signed by publish.dds.security.permissions_ca (" + openssl_reason() + ")";
}

std::string xml_escaped(const std::string& s) {
  std::string out;
  for (const char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

}  // namespace

std::string dds_security_setting(std::size_t file) {
  return "publish.dds.security." + std::string(kDdsSecurityKeys.at(file));
}

std::vector<DdsSecurityProblem> check_dds_security(const DdsSecuritySettings& s) {
  std::vector<DdsSecurityProblem> out;
  auto problem = [&](std::size_t f, const std::string& why) { out.push_back({f, s.path[f] + ": " + why}); };
  bool readable[kDdsSecurityFiles] = {};
  for (std::size_t f = 0; f < kDdsSecurityFiles; ++f) {
    const std::string why = unreadable(s.path[f]);
    readable[f] = why.empty();
    if (!why.empty()) problem(f, "cannot be read: " + why);
  }
  std::string why;
  std::optional<X509Ptr> identity_ca, certificate, permissions_ca;
  if (readable[kIdentityCa] && !(identity_ca = read_certificate(s.path[kIdentityCa], why))) problem(kIdentityCa, why);
  if (readable[kCertificate] && !(certificate = read_certificate(s.path[kCertificate], why)))
    problem(kCertificate, why);
  if (readable[kPermissionsCa] && !(permissions_ca = read_certificate(s.path[kPermissionsCa], why)))
    problem(kPermissionsCa, why);
  if (certificate && identity_ca) {
    if (const std::string v = verify_certificate(certificate->get(), identity_ca->get()); !v.empty())
      problem(kCertificate,
              v + "; expected the gateway's certificate from publish.dds.security.identity_ca, valid now");
  }
  if (readable[kPrivateKey]) {
    if (const std::string m = key_mode_problem(s.path[kPrivateKey]); !m.empty()) problem(kPrivateKey, m);
    BioPtr b = open_file(s.path[kPrivateKey]);
    KeyPtr key(b ? PEM_read_bio_PrivateKey(b.get(), nullptr, no_password, nullptr) : nullptr);
    if (!key)
      problem(kPrivateKey, "is no unencrypted PEM private key (" + openssl_reason() +
                               "); expected the key of publish.dds.security.certificate, without a password");
    else if (certificate && X509_check_private_key(certificate->get(), key.get()) != 1)
      problem(kPrivateKey, "is not the key of publish.dds.security.certificate (" + subject(certificate->get()) + ")");
    (void)openssl_reason();
  }
  for (const std::size_t f : {kGovernance, kPermissions})
    if (readable[f] && permissions_ca)
      if (const std::string v = verify_document(s.path[f], permissions_ca->get()); !v.empty()) problem(f, v);
  return out;
}

std::string dds_security_xml(const DdsSecuritySettings& s) {
  auto uri = [&](std::size_t f) {
    return "file:" + xml_escaped(std::filesystem::absolute(s.path[f]).lexically_normal().string());
  };
  // The plugins' libraries are left at Cyclone's defaults: Debian's libddsc finds its builtin
  // ones in /usr/lib/<triplet>/libddsc0debian.
  return "<Security><Authentication><IdentityCA>" + uri(kIdentityCa) + "</IdentityCA><IdentityCertificate>" +
         uri(kCertificate) + "</IdentityCertificate><PrivateKey>" + uri(kPrivateKey) +
         "</PrivateKey></Authentication><AccessControl><PermissionsCA>" + uri(kPermissionsCa) +
         "</PermissionsCA><Governance>" + uri(kGovernance) + "</Governance><Permissions>" + uri(kPermissions) +
         "</Permissions></AccessControl></Security>";
}

}  // namespace oegw::publish
