// The `publish` section: the FE samples on DDS and LCM, and the commands coming back.
#include "mapping/sections/sections.hpp"
#include "publish/lcm_url.hpp"

namespace oegw::mapping::sections {

namespace {

// `security: { identity_ca: …, certificate: …, private_key: …, permissions_ca: …, governance: …,
// permissions: … }`: every file required, each from the file's folder (config.hpp). Whether the
// files are what they must be is checked where OpenSSL is at hand (publish/dds_security.hpp:
// `oegw check`, `oegw run` and the publisher at start).
void read_dds_security(YamlReader& r, const MapEntry& e, DdsSecurityConfig& sec) {
  using S = DdsSecurityConfig;
  sec.section = r.loc(e.key);
  const std::vector<std::string_view> keys(S::kKeys.begin(), S::kKeys.end());
  const std::string expected =
      "a map with identity_ca, certificate, private_key, permissions_ca, governance, permissions (file paths, from "
      "the mapping file's folder)";
  const auto es = r.entries(e.value, "publish dds security", keys, expected);
  if (!e.value.IsMap()) return;
  for (std::size_t i = 0; i < S::kFiles; ++i) {
    const std::string key(S::kKeys[i]);
    const auto* x = r.find(es, key);
    if (x == nullptr) {
      r.error(e.key, "publish dds security has no " + key + "; expected " + expected);
      continue;
    }
    sec.where[i] = r.loc(x->value);
    if (auto v = r.string(*x, key)) sec.path[i] = r.path(*v);
  }
}

// A section written is enabled unless it says `enabled: false`.
void read_dds(YamlReader& r, const MapEntry& e, DdsConfig& d) {
  d.enabled = true;
  d.where = r.loc(e.key);
  const auto ds = r.entries(e.value, "publish dds", {"enabled", "domain", "partition", "network", "security"},
                            "a map with enabled, domain, partition, network, security");
  if (const auto* x = r.find(ds, "enabled"))
    if (auto b = r.boolean(*x, "enabled")) d.enabled = *b;
  r.set_int(ds, "domain", "domain", 0, 232, d.domain);
  if (const auto* x = r.find(ds, "partition"))
    if (auto s = r.string(*x, "partition")) d.partition = *s;
  if (const auto* x = r.find(ds, "network")) {
    d.network_where = r.loc(x->value);
    if (auto s = r.string(*x, "network")) d.network = *s;
  }
  if (const auto* x = r.find(ds, "security")) read_dds_security(r, *x, d.security.emplace());
}

// The one rule for the URL (publish/lcm_url.hpp): no link-local group beyond this host.
void check_lcm_url(YamlReader& r, const MapEntry& e) {
  const std::string url = e.value.Scalar();
  const auto send = publish::link_local_send(url);
  if (!send) return;
  r.error(e.value, "publish lcm url '" + url + "' sends to the link-local group " + send->group + " with ttl '" +
                       send->ttl +
                       "', so every host on the network would receive it; expected ttl=0 (this host only) "
                       "or a 239.x.x.x group for a network, e.g. udpm://239.255.76.67:7667?ttl=1");
}

void read_lcm(YamlReader& r, const MapEntry& e, LcmConfig& l) {
  l.enabled = true;
  l.where = r.loc(e.key);
  const auto ls = r.entries(e.value, "publish lcm", {"enabled", "url", "channel_prefix"},
                            "a map with enabled, url, channel_prefix");
  if (const auto* x = r.find(ls, "enabled"))
    if (auto b = r.boolean(*x, "enabled")) l.enabled = *b;
  if (const auto* x = r.find(ls, "url"))
    if (auto s = r.string(*x, "url")) {
      l.url = *s;
      l.url_where = r.loc(x->value);
      check_lcm_url(r, *x);
    }
  if (const auto* x = r.find(ls, "channel_prefix"))
    if (auto s = r.string(*x, "channel_prefix")) l.channel_prefix = *s;
}

}  // namespace

void read_publish(YamlReader& r, const MapEntry& sec, PublishConfig& p) {
  const auto es = r.entries(sec.value, "publish", {"period_ms", "dds", "lcm"}, "a map with period_ms, dds, lcm");
  r.set_int(es, "period_ms", "period_ms", 1, 60000, p.period_ms);
  if (const auto* e = r.find(es, "dds")) read_dds(r, *e, p.dds);
  if (const auto* e = r.find(es, "lcm")) read_lcm(r, *e, p.lcm);
}

}  // namespace oegw::mapping::sections
