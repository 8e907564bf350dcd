#!/usr/bin/env bash
# Refresh the replay viewer's three.js from the npm registry.
#
#   replay/vendor/three/refresh.sh          install the version pinned in package-lock.json
#                                           and copy its files here (also what CI runs to
#                                           check that the committed files are npm's)
#   replay/vendor/three/refresh.sh 0.188.0  pin another version first (rewrites both JSON files)
#   replay/vendor/three/refresh.sh --check  only compare the committed files with npm's
#
# The files are embedded into every replay HTML at build time (include_str!), so the
# Rust build needs neither npm nor the network. Files taken from the package:
# build/three.core.js, build/three.module.js, examples/jsm/controls/OrbitControls.js, LICENSE.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cp "$here/package.json" "$here/package-lock.json" "$tmp/"
cd "$tmp"
mode=copy
if [[ "${1:-}" == "--check" ]]; then
    mode=check
elif [[ -n "${1:-}" ]]; then
    npm install --no-audit --no-fund --save-exact --omit-lockfile-registry-resolved=false "three@$1"
    cp package.json package-lock.json "$here/"
fi
# `npm ci` installs exactly what the lock says and fails if the tarball's hash
# differs from the lock's `integrity`.
npm ci --no-audit --no-fund --ignore-scripts
src=node_modules/three
files=(build/three.core.js build/three.module.js examples/jsm/controls/OrbitControls.js LICENSE)
status=0
for f in "${files[@]}"; do
    name="$(basename "$f")"
    if [[ $mode == check ]]; then
        if ! cmp -s "$src/$f" "$here/$name"; then
            echo "replay/vendor/three/$name differs from three@$(node -p "require('./$src/package.json').version") on npm ($f)" >&2
            status=1
        fi
    else
        cp "$src/$f" "$here/$name"
    fi
done
if [[ $mode == copy ]]; then
    echo "copied three@$(node -p "require('./$src/package.json').version") into $here"
elif [[ $status == 0 ]]; then
    echo "replay/vendor/three matches three@$(node -p "require('./$src/package.json').version") from npm"
fi
exit $status
