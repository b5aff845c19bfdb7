#!/usr/bin/env bash
# Runs one test ELF under QEMU and decodes its defmt output.
#   qemu-run.sh MACHINE ELF
# Exit code: QEMU's, which is the firmware's semihosting exit code (0 = every test passed).
# -icount shift=0: one instruction per virtual nanosecond, so the SysTick clock and every
# run are deterministic; a run longer than QEMU_TIMEOUT seconds (default 120) fails.
set -euo pipefail
machine=$1
elf=$2
case $machine in
    microbit) cpu=cortex-m0 ;;
    mps2-an386) cpu=cortex-m4 ;;
    *) echo "qemu-run.sh: unknown machine $machine" >&2; exit 2 ;;
esac
set +e
timeout "${QEMU_TIMEOUT:-120}" qemu-system-arm -machine "$machine" -cpu "$cpu" -nographic \
    -monitor none -serial null -icount shift=0,sleep=off \
    -semihosting-config enable=on,target=native -kernel "$elf" \
    | defmt-print -e "$elf"
status=("${PIPESTATUS[@]}")
set -e
if [ "${status[0]}" -ne 0 ]; then
    echo "qemu-run.sh: $(basename "$elf") on $machine exited with ${status[0]}" >&2
    exit "${status[0]}"
fi
exit "${status[1]}"
