#!/usr/bin/env bash
# Footprint of the firmware per target, measured: builds the release
# firmware for each Cortex-M target, reads its sections with GNU `size -A`
# (binutils; `llvm-size -A` or `arm-none-eabi-size -A` print the same) and
# runs it under QEMU (mps2-an386) for the stack-painting and table-size lines
# the firmware prints itself, then the RISC-V firmware (targets/riscv32,
# sections only: it does not paint its stack). Prints Markdown tables.
# Usage: targets/footprint.sh
#
# flash      = .vector_table + .text + .rodata + .data (initial values live in flash)
# static RAM = .data + .bss + .uninit (the stack comes on top: see the stack columns)
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
SIZE=${SIZE:-size}
command -v "$SIZE" >/dev/null || SIZE=llvm-size
command -v qemu-system-arm >/dev/null || { echo "qemu-system-arm is not installed" >&2; exit 1; }

sec() { # elf section -> bytes (0 if absent)
    "$SIZE" -A "$1" | awk -v s="$2" '$1 == s {print $2; found=1} END {if (!found) print 0}'
}
field() { # line-record key <<< output
    awk -v r="$1" -v k="$2" '$1 == r { for (i = 2; i <= NF; i++) { split($i, kv, "="); if (kv[1] == k) print kv[2] } }'
}

echo "| target | core | flash (text + rodata + vectors) | static RAM (data + bss) | of which solver tables | peak stack: profiler (5 tables) | peak stack: solver | peak stack: one pixel | peak stack: 16×16 tile | peak stack: one pixel, narrow | peak stack: 16×16 tile, narrow |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
breakdown=""
for t in thumbv7em-none-eabihf thumbv6m-none-eabi; do
    cargo build --release --locked -q ${opt[@]+"${opt[@]}"} --target "$t"
    elf=target/$t/release/nerflex-firmware-m4
    run=$(qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
        -semihosting-config enable=on,target=native -kernel "$elf")
    grep -q '^done' <<<"$run" || { echo "$t: the firmware did not finish:" >&2; echo "$run" >&2; exit 1; }
    vt=$(sec "$elf" .vector_table); tx=$(sec "$elf" .text); ro=$(sec "$elf" .rodata)
    da=$(sec "$elf" .data); bs=$(sec "$elf" .bss); un=$(sec "$elf" .uninit)
    case $t in
        thumbv7em-none-eabihf) core="Cortex-M4F (ARMv7E-M + FPU)" ;;
        thumbv6m-none-eabi) core="Cortex-M0/M0+ (ARMv6-M)" ;;
    esac
    # Code by origin, from the symbol table (nm -S; LTO inlines the core into
    # the firmware's functions, so "nerflex" is the core plus its callers).
    breakdown+=$(nm -S -C "$elf" | grep -E '^[0-9a-f]+ [0-9a-f]+ [tTwW] ' |
        while read -r _ sz _ name; do echo "$((16#$sz)) $name"; done |
        awk -v t="$t" -v text="$tx" '{ sz = $1; $1 = ""; n = $0
            if (n ~ /nerflex/ && n !~ /Display|Debug/) c = 1
            else if (n ~ /compiler_builtins|__aeabi|^ __|^ mem(cpy|set|move|cmp)|libm::/) c = 2
            else if (n ~ /fmt|flt2dec|bignum|Display|Debug|core::str/) c = 3
            else c = 4
            s[c] += sz; all += sz }
            END { printf "| `%s` | %d B | %d B | %d B | %d B |\n", t, s[1], s[2], s[3], s[4] + text - all }')
    breakdown+=$'\n'
    echo "| \`$t\` | $core | $((vt + tx + ro + da)) B ($tx + $ro + $vt$( [ "$da" != 0 ] && echo " + $da")) | $((da + bs + un)) B | $(field memory solver_static_bytes <<<"$run") B | $(field stack profile_bytes <<<"$run") B | $(field stack solver_bytes <<<"$run") B | $(field stack shade_pixel_bytes <<<"$run") B | $(field stack shade_tile_bytes <<<"$run") B | $(field stack narrow_pixel_bytes <<<"$run") B | $(field stack narrow_tile_bytes <<<"$run") B |"
done

echo
echo "Code (.text) by origin:"
echo
echo "| target | nerflex (core + firmware) | compiler builtins + libm (soft float, 64/128-bit division, memcpy) | formatting (core::fmt, printing numbers) | runtime, panic, other |"
echo "|---|---|---|---|---|"
printf "%s" "$breakdown"

# RISC-V (QEMU virt): flash = what a ROM would hold (text + rodata + data).
echo
echo "| target | core | code + constants (text + rodata + data) | static RAM (data + bss) | stack reserved |"
echo "|---|---|---|---|---|"
(
    cd ../riscv32
    cargo build --release --locked -q
    elf=target/riscv32imac-unknown-none-elf/release/nerflex-firmware-riscv32
    run=$(timeout 60 qemu-system-riscv32 -machine virt -nographic -bios none -kernel "$elf")
    grep -q '^done' <<<"$run" || { echo "riscv32: the firmware did not finish:" >&2; echo "$run" >&2; exit 1; }
    tx=$(sec "$elf" .text); ro=$(sec "$elf" .rodata); da=$(sec "$elf" .data)
    bs=$(sec "$elf" .bss); st=$(sec "$elf" .stack)
    echo "| \`riscv32imac-unknown-none-elf\` | RV32IMAC (QEMU virt) | $((tx + ro + da)) B ($tx + $ro + $da) | $((da + bs)) B | $st B |"
)
