#!/usr/bin/env bash
# Instructions executed on the emulated Cortex-M4 (and the Cortex-M0 build)
# per call of the firmware's profiler step, MCK solve and MLP shade.
# Usage: targets/m4-icount.sh [target...]   (default: both Cortex-M targets)
#
# QEMU runs the firmware one instruction per translation block
# (-singlestep) and logs every executed block (-d exec,nochain); awk counts
# the log lines from a function's entry address until execution reaches an
# instruction right after one of its call sites (so callees are included).
# Addresses come from the ELF (nm, llvm-objdump). QEMU does not model
# cycles: these are instruction counts, not cycle counts.
set -euo pipefail
cd "$(dirname "$0")/cortex-m4"
# CORE_OPT=s|z|0..3 overrides the optimisation level of nerflex-core in the
# firmware (default: Cargo.toml's, 3; the rest of the firmware is "s").
opt=()
case "${CORE_OPT:-}" in
    "") ;;
    s | z) opt=(--config "profile.release.package.nerflex-core.opt-level=\"$CORE_OPT\"") ;;
    *) opt=(--config "profile.release.package.nerflex-core.opt-level=$CORE_OPT") ;;
esac
OBJDUMP=${OBJDUMP:-llvm-objdump}
command -v "$OBJDUMP" >/dev/null || { echo "$OBJDUMP is not installed (apt-get install llvm)" >&2; exit 1; }
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(thumbv7em-none-eabihf thumbv6m-none-eabi)

# name in the table | symbol (demangled, without hash)
funcs=(
    "five profiles → 5 × 45 configurations|nerflex_firmware_m4::evaluate_profiles"
    "one MCK solve (5 × 45, 0.1 MB units), both budgets|nerflex_firmware_m4::plan"
    "one shaded pixel, exact shader (FixedMlp::shade)|nerflex_core::shader::FixedMlp::shade"
    "one shaded pixel, narrow shader (NarrowMlp::shade)|nerflex_core::shader::narrow::NarrowMlp::shade"
)

echo "| target | operation | calls | instructions per call: min | mean | max |"
echo "|---|---|---|---|---|---|"
for t in "${targets[@]}"; do
    cargo build --release --locked -q ${opt[@]+"${opt[@]}"} --target "$t"
    elf=target/$t/release/nerflex-firmware-m4
    dis=$("$OBJDUMP" -d --no-show-raw-insn -C "$elf")
    spec=""
    for f in "${funcs[@]}"; do
        sym=${f#*|}
        start=$(nm -C "$elf" | awk -v s="$sym" '$3 == s {print $1}' | head -1)
        [ -n "$start" ] || { echo "$t: symbol $sym not found" >&2; exit 1; }
        start=$(printf '%08x' $((16#$start & ~1)))
        # Return addresses: the instruction after each `bl <sym::h…>` (4 bytes).
        rets=$(grep -E "bl[[:space:]]+0x[0-9a-f]+ <${sym}::h[0-9a-f]+>" <<<"$dis" |
            awk '{a = $1; sub(":", "", a); printf "%08x ", strtonum("0x" a) + 4}' 2>/dev/null ||
            true)
        if [ -z "$rets" ]; then
            rets=$(grep -E "bl[[:space:]]+0x[0-9a-f]+ <${sym}::h[0-9a-f]+>" <<<"$dis" |
                while read -r a _; do printf '%08x ' $((16#${a%:} + 4)); done)
        fi
        [ -n "$rets" ] || { echo "$t: no call site of $sym" >&2; exit 1; }
        spec+="${f%%|*}|$start|$rets;"
    done
    qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
        -semihosting-config enable=on,target=native -kernel "$elf" \
        -singlestep -d exec,nochain 2>&1 >/dev/null |
        awk -v spec="$spec" -v t="$t" '
        BEGIN {
            nf = split(spec, fs, ";")
            for (i = 1; i < nf; i++) {
                split(fs[i], p, "|"); name[i] = p[1]; start[i] = p[2]
                nr = split(p[3], r, " ")
                for (j = 1; j <= nr; j++) ret[i, r[j]] = 1
                min[i] = -1
            }
            nf--
        }
        /^Trace/ {
            k = index($0, "["); pc = substr($0, k + 10, 8)
            for (i = 1; i <= nf; i++) {
                if (active[i]) {
                    if ((i, pc) in ret) {
                        active[i] = 0; calls[i]++; sum[i] += n[i]
                        if (min[i] < 0 || n[i] < min[i]) min[i] = n[i]
                        if (n[i] > max[i]) max[i] = n[i]
                    } else n[i]++
                } else if (pc == start[i]) { active[i] = 1; n[i] = 1 }
            }
        }
        END {
            for (i = 1; i <= nf; i++)
                printf "| `%s` | %s | %d | %d | %.0f | %d |\n", t, name[i], calls[i], min[i], sum[i] / (calls[i] ? calls[i] : 1), max[i]
        }'
done
