#!/bin/bash
# rack-gui's symbolization of mode-switch report files (issue 21 item 4): how long a
# file of N reports takes the first time, how long one appended report takes, and
# how long rack-gui needs to exit (after the first pass, and during it). Beside it,
# the reference: rack-backtrace over the whole file, which is what rack-gui before
# issue 21 ran again whenever a report was added (and waited for on exit).
#
#   bench/gui_reports.sh BUILD_DIR REPORT_FILE [N]
#
# REPORT_FILE: any rackd report file with at least one complete report (its first
# report is copied N times, default 1830, with new sequence numbers).
set -eu
build=$1 src=$2 n=${3:-1830}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$src" "$n" "$work/rackd-1.report" "$work/one.txt" <<'EOF'
import sys
src = open(sys.argv[1]).read().splitlines()
n = int(sys.argv[2])
head = [l for l in src if not l.startswith(('report', 'detail', 'frame', 'end'))]
first, block = None, []
for l in src:
    if l.startswith('report '):
        if first is not None: break
        first = l.split()[1]
    if first is not None: block.append(l)
def copy(i):
    out = []
    for l in block:
        if l.startswith('report '): l = 'report %d ' % i + l.split(' ', 2)[2]
        if l.startswith('end '): l = 'end %d' % i
        out.append(l)
    return out
lines = list(head)
for i in range(1, n + 1): lines += copy(i)
open(sys.argv[3], 'w').write('\n'.join(lines) + '\n')
open(sys.argv[4], 'w').write('\n'.join(copy(n + 1)) + '\n')
EOF
mkdir "$work/d"
cp "$work/rackd-1.report" "$work/d/"
start=$(date +%s.%N)
"$build/tools/rack-backtrace" "$work/rackd-1.report" > /dev/null 2>&1 || true
echo "reference: rack-backtrace over the whole file ($n reports): $(echo "$(date +%s.%N) - $start" | bc) s"
run_gui() {
  "$build/tools/gui/rack-gui" --port 0 --lcm "udpm://239.255.76.67:$((20000 + RANDOM % 1000))?ttl=0" \
    --reports "$work/d" --web "$(dirname "$0")/../tools/gui/web/dist" > "$work/gui.log" 2>&1 &
  gui=$!
}
stop_gui() {
  local t=$(date +%s.%N)
  kill -TERM $gui; wait $gui || true
  echo "rack-gui exit after SIGTERM ($1): $(echo "$(date +%s.%N) - $t" | bc) s"
}
run_gui
for i in $(seq 1 600); do grep -q "symbolized" "$work/gui.log" && break; sleep 0.1; done
grep symbolized "$work/gui.log" | sed 's/^/first pass: /'
cat "$work/one.txt" >> "$work/d/rackd-1.report"
for i in $(seq 1 100); do [ "$(grep -c symbolized "$work/gui.log")" -ge 2 ] && break; sleep 0.1; done
grep symbolized "$work/gui.log" | tail -1 | sed 's/^/one report appended: /'
stop_gui "after the first pass"
rm -f "$work/d/rackd-1.report"; cp "$work/rackd-1.report" "$work/d/"
run_gui
sleep 2
stop_gui "2 s into the first pass"
