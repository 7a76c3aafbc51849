#!/usr/bin/env bash
# Installs the VM tier's node-canopen host
# (docs/developer/vm-tier.md#vm_node_peer-node-canopen-against-oegw) into DEST from the committed
# lockfile: `npm ci`, packages from the npm registry only. The two native addons (socketcan, and
# canopen's node-crc) are compiled by the pinned node-gyp against the headers of the node that will
# run them, /usr/include/node (`--nodedir=/usr`: Debian's libnode-dev, or a nodejs package that
# ships its headers), so nothing is downloaded beside the registry's tarballs. Idempotent: an
# install of this package.json and lockfile for this node in DEST is kept. Usage: install.sh DEST
# (CTest: vm_node_peer_install, DEST = build/tests/vm/node_peer)
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
dest=${1:?usage: install.sh DEST}

die() { echo "node peer: $*" >&2; exit 1; }
command -v node >/dev/null || die "no node: run scripts/install-deps.sh (nodejs, npm, libnode-dev)"
command -v npm >/dev/null || die "no npm: run scripts/install-deps.sh (nodejs, npm, libnode-dev)"
[[ -r /usr/include/node/node.h ]] || die "no /usr/include/node/node.h (Node's headers for the addons): run scripts/install-deps.sh (libnode-dev)"

# What an install depends on: the two files and the node that compiled the addons.
stamp="$(cat "$here/package.json" "$here/package-lock.json" | sha256sum | cut -c1-16) node $(node --version)"
loads() {  # the packages load (the addons' .node files with them; a channel needs AF_CAN, not asked here)
  (cd "$dest" && node -e "require('canopen'); require('socketcan')") 2>&1
}
if [[ -f $dest/.installed && $(<"$dest/.installed") == "$stamp" ]] && loads >/dev/null; then
  echo "node peer: $stamp already in $dest"
  exit 0
fi

mkdir -p "$dest"
rm -f "$dest/.installed"
cp "$here/package.json" "$here/package-lock.json" "$dest/"
# node-gyp runs gyp with the python3 that PYTHON names; Debian's is the one install-deps guarantees
# (a python3 earlier on PATH, e.g. a pyenv shim, need not be able to run it).
python=/usr/bin/python3
[[ -x $python ]] || python=$(command -v python3)
echo "node peer: npm ci in $dest (node $(node --version), npm $(npm --version))"
(cd "$dest" && PYTHON=$python npm ci --nodedir=/usr --no-audit --no-fund --loglevel=warn) ||
  die "npm ci failed in $dest"
for addon in node_modules/socketcan/build/Release/can.node node_modules/node-crc/build/Release/crc.node; do
  [[ -f $dest/$addon ]] || die "$addon was not built (npm ran no install script?)"
done
out=$(loads) || die "the installed packages do not load: $out"
echo "$stamp" >"$dest/.installed"
echo "node peer: installed canopen $(cd "$dest" && node -p "require('canopen/package.json').version"), socketcan $(cd "$dest" && node -p "require('socketcan/package.json').version") in $dest"
