#!/usr/bin/env bash
# make test-offline: the offline install, end to end, as a vehicle computer does it. A fresh clone
# of HEAD gets its wheels (`make wheels`, the one step that uses the network), then installs from
# them with no network at all (a new network namespace, `unshare -n` or `-rn`, where the OS permits
# it; else it says it is NOT isolated) and runs the demo in the new venv. Prints what it used.
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
git clone --quiet . "$work/overdrive"
cd "$work/overdrive"
start=$(date +%s)
make --no-print-directory wheels >/dev/null 2> >(grep -v "^WARNING: Location" >&2)
echo "test-offline: $(ls wheels | wc -l) files, $(du -sh wheels | cut -f1) in wheels/ ($(($(date +%s) - start)) s)"
if unshare -n true 2>/dev/null; then
    isolate=(unshare -n)
    how="no network (unshare -n)"
elif unshare -rn true 2>/dev/null; then
    isolate=(unshare -rn)
    how="no network (unshare -rn, a user namespace)"
else
    isolate=()
    how="NOT network-isolated (no network namespace permitted here): only --no-index keeps pip off the index"
fi
start=$(date +%s)
"${isolate[@]}" make --no-print-directory install-offline >/dev/null
echo "test-offline: installed from wheels/ with $how ($(($(date +%s) - start)) s)"
"${isolate[@]}" .venv/bin/overdrive sim scenarios/demo.yaml --quiet --out runs/demo >/dev/null
echo "test-offline: demo ran offline, exit 0, summary at runs/demo/summary.json"
