#!/bin/sh
# Makes a working DDS Security set for one cab (OMG DDS Security 1.1, as Cyclone DDS's builtin
# plugins read it) with Debian's openssl:
#   ca.pem, ca.key            the cab's CA: identity CA and permissions CA in one. ca.key signs
#                             everything below; keep it on the computer that runs this script,
#                             never on the controller
#   gateway.pem, gateway.key  the gateway's identity (publish.dds.security.certificate, .private_key)
#   app.pem, app.key          the machine application: reads every input and the status, commands
#                             the indicators and displays
#   monitor.pem, monitor.key  a read-only participant: reads inputs and status, commands nothing
#   governance.xml, .p7s      the domain's rules, signed (S/MIME): no unauthenticated participant,
#                             join, read and write access control on every topic, the data
#                             protected as --protection says
#   permissions.xml, .p7s     one grant per identity above, signed; everything else is denied
# Usage: make-dds-security.sh [--domain D] [--partition P] [--protection none|sign|encrypt]
#                             [--days N] OUTDIR
#   --domain      the publish.dds.domain the grants are for (default 0)
#   --partition   the publish.dds.partition (default oegw)
#   --protection  none: authentication and access control, data in clear; sign: every data
#                 submessage carries a MAC, discovery signed; encrypt (default): the payload
#                 encrypted (AES-GCM) and the submessages signed, discovery encrypted
#   --days        validity of the certificates and the permissions (default 365)
# The keys are EC P-256 (Cyclone's builtin authentication takes RSA-2048 or EC prime256v1) and
# written mode 0600. OUTDIR is created; existing files in it are overwritten.
set -eu

domain=0 partition=oegw protection=encrypt days=365
usage() { echo "usage: $0 [--domain D] [--partition P] [--protection none|sign|encrypt] [--days N] OUTDIR" >&2; exit 64; }
while [ $# -gt 0 ]; do
  case $1 in
    --domain) [ $# -ge 2 ] || usage; domain=$2; shift 2 ;;
    --partition) [ $# -ge 2 ] || usage; partition=$2; shift 2 ;;
    --protection) [ $# -ge 2 ] || usage; protection=$2; shift 2 ;;
    --days) [ $# -ge 2 ] || usage; days=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -eu/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    -*) echo "$0: unknown option $1" >&2; usage ;;
    *) break ;;
  esac
done
[ $# -eq 1 ] || usage
out=$1
case $domain in ''|*[!0-9]*) echo "$0: --domain $domain: expected 0..232" >&2; exit 64 ;; esac
[ "$domain" -le 232 ] || { echo "$0: --domain $domain: expected 0..232" >&2; exit 64; }
case $days in ''|*[!0-9]*) echo "$0: --days $days: expected a number of days" >&2; exit 64 ;; esac
case $partition in ''|*[\<\>\&\"\']*) echo "$0: --partition '$partition': expected a name without < > & quotes" >&2; exit 64 ;; esac
case $protection in
  none) data=NONE meta=NONE disc=NONE ;;
  sign) data=NONE meta=SIGN disc=SIGN ;;
  encrypt) data=ENCRYPT meta=SIGN disc=ENCRYPT ;;
  *) echo "$0: --protection $protection: expected none, sign or encrypt" >&2; exit 64 ;;
esac
command -v openssl >/dev/null || { echo "$0: openssl is missing (apt-get install openssl)" >&2; exit 69; }

mkdir -p "$out"
umask 077
cd "$out"

# The CA: self-signed, the root of both identities and permissions.
openssl ecparam -name prime256v1 -genkey -noout -out ca.key 2>/dev/null
openssl req -new -x509 -key ca.key -out ca.pem -days "$days" -subj "/O=oegw cab/CN=oegw cab CA" \
  -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign,digitalSignature

# One identity: its key, a request, the certificate the CA signs.
identity() {
  openssl ecparam -name prime256v1 -genkey -noout -out "$1.key" 2>/dev/null
  openssl req -new -key "$1.key" -out "$1.csr" -subj "/O=oegw cab/CN=$2"
  printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n' >"$1.ext"
  openssl x509 -req -in "$1.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -days "$days" -out "$1.pem" \
    -extfile "$1.ext" 2>/dev/null
  rm -f "$1.csr" "$1.ext"
}
identity gateway oegw-gateway
identity app oegw-app
identity monitor oegw-monitor
rm -f ca.srl
chmod 0644 ca.pem gateway.pem app.pem monitor.pem

# The subject as the permissions must name it: RFC 2253, as Cyclone compares it.
subject() { openssl x509 -noout -subject -nameopt RFC2253 -in "$1.pem" | sed 's/^subject=//'; }

topics_in="oegw/joystick oegw/pedal oegw/wheel oegw/encoder oegw/buttons oegw/status"
topics_cmd="oegw/indicators oegw/display"
topic_list() { for t in $1; do printf '            <topic>%s</topic>\n' "$t"; done; }
rule() {  # publish|subscribe TOPICS
  printf '        <%s>\n          <topics>\n%s\n          </topics>\n' "$1" "$(topic_list "$2")"
  printf '          <partitions><partition>%s</partition></partitions>\n        </%s>\n' "$partition" "$1"
}
grant() {  # NAME IDENTITY PUBLISHED SUBSCRIBED
  cat <<EOF
    <grant name="$1">
      <subject_name>$(subject "$2")</subject_name>
      <validity><not_before>$not_before</not_before><not_after>$not_after</not_after></validity>
      <allow_rule>
        <domains><id>$domain</id></domains>
$( [ -n "$3" ] && rule publish "$3" )
$( [ -n "$4" ] && rule subscribe "$4" )
      </allow_rule>
      <default>DENY</default>
    </grant>
EOF
}
not_before=$(date -u -d "-1 day" +%Y-%m-%dT%H:%M:%S)  # a day of clock skew between the computers
not_after=$(date -u -d "+$days days" +%Y-%m-%dT%H:%M:%S)

cat >governance.xml <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<!-- oegw: made by scripts/make-dds-security.sh (protection $protection) -->
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id>$domain</id></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>$disc</discovery_protection_kind>
      <liveliness_protection_kind>$disc</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>$( [ "$disc" = NONE ] && echo false || echo true )</enable_discovery_protection>
          <enable_liveliness_protection>false</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>$meta</metadata_protection_kind>
          <data_protection_kind>$data</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF

cat >permissions.xml <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<!-- oegw: made by scripts/make-dds-security.sh; one grant per identity, everything else denied -->
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">
  <permissions>
$(grant oegw-gateway gateway "$topics_in" "$topics_cmd")
$(grant oegw-app app "$topics_cmd" "$topics_in")
$(grant oegw-monitor monitor "" "$topics_in")
  </permissions>
</dds>
EOF

# S/MIME signed by the CA (its certificate included), as the builtin access control reads them.
for doc in governance permissions; do
  openssl smime -sign -in "$doc.xml" -text -out "$doc.p7s" -signer ca.pem -inkey ca.key
done
chmod 0644 governance.xml governance.p7s permissions.xml permissions.p7s
echo "$out: ca.pem gateway.{pem,key} app.{pem,key} monitor.{pem,key} governance.p7s permissions.p7s (domain $domain, partition $partition, protection $protection, $days days); keep ca.key off the controller"
