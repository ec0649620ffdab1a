#!/usr/bin/env bash
# Instructions executed on the emulated RISC-V core (QEMU virt, riscv32imac)
# per shaded pixel, exact and narrow shader. Usage: targets/riscv-icount.sh
#
# The RISC-V firmware shades each pixel through its own non-inlined call
# (`pixel_exact`, `pixel_narrow`). QEMU runs it one instruction per
# translation block (-singlestep) and logs every executed block
# (-d exec,nochain); awk counts from a function's entry address to one of
# its own `ret` instructions, inclusive (callees included). QEMU does not
# model cycles: these are instruction counts.
set -euo pipefail
cd "$(dirname "$0")/riscv32"
OBJDUMP=${OBJDUMP:-llvm-objdump}
command -v "$OBJDUMP" >/dev/null || { echo "$OBJDUMP is not installed (apt-get install llvm)" >&2; exit 1; }
cargo build --release --locked -q
elf=target/riscv32imac-unknown-none-elf/release/nerflex-firmware-riscv32
dis=$("$OBJDUMP" -d --no-show-raw-insn -C "$elf")
spec=""
for f in "one shaded pixel, exact shader (FixedMlp::shade)|nerflex_firmware_riscv32::pixel_exact" \
    "one shaded pixel, narrow shader (NarrowMlp::shade)|nerflex_firmware_riscv32::pixel_narrow"; do
    sym=${f#*|}
    # The function's body: from its label to the next function label.
    body=$(awk -v s="<${sym}::h" '/^[0-9a-f]+ <[^.]/ {if (on) exit; if (index($0, s)) {on = 1; next}} on' <<<"$dis")
    start=$(grep -E "^[0-9a-f]+ <${sym}::h" <<<"$dis" | awk '{print $1}')
    [ -n "$start" ] || { echo "symbol $sym not found" >&2; exit 1; }
    rets=$(awk '$2 == "ret" {a = $1; sub(":", "", a); while (length(a) < 8) a = "0" a; printf "%s ", a}' <<<"$body")
    [ -n "$rets" ] || { echo "no ret in $sym" >&2; exit 1; }
    spec+="${f%%|*}|$start|$rets;"
done
echo "| target | operation | calls | instructions per call: min | mean | max |"
echo "|---|---|---|---|---|---|"
timeout 300 qemu-system-riscv32 -machine virt -nographic -bios none -kernel "$elf" \
    -singlestep -d exec,nochain 2>&1 >/dev/null |
    awk -v spec="$spec" '
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
                n[i]++
                if ((i, pc) in ret) {
                    active[i] = 0; calls[i]++; sum[i] += n[i]
                    if (min[i] < 0 || n[i] < min[i]) min[i] = n[i]
                    if (n[i] > max[i]) max[i] = n[i]
                }
            } else if (pc == start[i]) { active[i] = 1; n[i] = 1 }
        }
    }
    END {
        for (i = 1; i <= nf; i++)
            printf "| `riscv32imac-unknown-none-elf` | %s | %d | %d | %.0f | %d |\n", name[i], calls[i], min[i], sum[i] / (calls[i] ? calls[i] : 1), max[i]
    }'
