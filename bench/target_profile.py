#!/usr/bin/env python3
"""Where the firmware's budget run spends its instructions, by source function and line.

Usage: bench/target_profile.py [TOP]     (run bench/target.sh first: it builds the firmware)

Runs the firmware in QEMU with the runner of firmware/.cargo/config.toml plus TCG's execution
log (`-d in_asm,exec,nochain`), streamed through a pipe rather than written out (it runs to
gigabytes). Every executed translation block adds its instructions; counting stops where the
profile variants begin, so the figures cover calibration, the budget run and its bad input.
With llvm-symbolizer on PATH each instruction is charged to the innermost Kestrel function it
was inlined from, with its source line; without it, to the ELF symbol that contains it.
The boot-time check of the DSP instructions (firmware/src/dsp_check.rs) is left out: it is not
part of the budget run.
A diagnosis tool: CI does not run it.
"""

import collections
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import tomllib

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from target_report import read_elf  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "firmware")
ELF = os.path.join(FIRMWARE, "target", "thumbv7em-none-eabihf", "release", "firmware")
# The first block of this function ends the budget run (see firmware/src/profile.rs).
STOP_SYMBOL = "7profile3run"
# A window of the run instead: PROFILE_FROM and PROFILE_TO name symbol fragments (mangled), for
# example PROFILE_FROM=6sensor3run PROFILE_TO=7profile3run for the flow-sensor preset alone.
START_SYMBOL = os.environ.get("PROFILE_FROM")
STOP_SYMBOL = os.environ.get("PROFILE_TO", STOP_SYMBOL)
# Functions whose own instructions are not counted (symbol name fragments).
SKIPPED_SYMBOLS = ("9dsp_check3run",)


def skipped_ranges():
    """Address ranges of the functions in SKIPPED_SYMBOLS."""
    _, symbols = read_elf(ELF)
    return [(addr, addr + size) for name, addr, size, _ in symbols
            if any(fragment in name for fragment in SKIPPED_SYMBOLS)]


def runner():
    with open(os.path.join(FIRMWARE, ".cargo", "config.toml"), "rb") as f:
        config = tomllib.load(f)
    return shlex.split(config["target"]["thumbv7em-none-eabihf"]["runner"])


def trace(log_path):
    """Instructions executed per guest address, up to the stop symbol."""
    blocks = {}
    executions = collections.Counter()
    skipped = skipped_ranges()
    current = None
    counting = START_SYMBOL is None
    with open(log_path, errors="replace") as log:
        for line in log:
            if line.startswith("Trace"):
                inside = line.split("[", 1)[1]
                pc = int(inside.split("/", 2)[1], 16)
                if STOP_SYMBOL in inside:
                    break
                counting = counting or START_SYMBOL in inside
                if counting and not any(start <= pc < end for start, end in skipped):
                    executions[pc] += 1
            elif line.startswith("IN:"):
                current = None
            elif line.startswith("0x") and ":" in line[:12]:
                address = int(line[:10], 16)
                if current is None:
                    current = address
                    blocks[current] = []
                blocks[current].append(address)
            else:
                current = None
    per_address = collections.Counter()
    for start, count in executions.items():
        for address in blocks.get(start, ()):
            per_address[address] += count
    return per_address


def run_qemu():
    with tempfile.TemporaryDirectory() as tmp:
        fifo = os.path.join(tmp, "exec.log")
        os.mkfifo(fifo)
        command = runner() + [ELF, "-d", "in_asm,exec,nochain", "-D", fifo]
        qemu = subprocess.Popen(command, stdout=subprocess.DEVNULL)
        try:
            counts = trace(fifo)
        finally:
            qemu.kill()
            qemu.wait()
    return counts


def by_symbolizer(counts, symbolizer):
    addresses = sorted(counts)
    query = "\n".join(hex(a) for a in addresses)
    result = subprocess.run([symbolizer, "--inlines", "--functions=linkage", "--demangle", "-e", ELF],
                            input=query, capture_output=True, text=True, check=True).stdout
    functions = collections.Counter()
    lines = collections.Counter()
    for address, block in zip(addresses, result.strip("\n").split("\n\n")):
        frames = block.split("\n")
        pairs = list(zip(frames[0::2], frames[1::2]))
        name, location = next(((f, loc) for f, loc in pairs if "kestrel" in f), pairs[0])
        name = name.rsplit("::h", 1)[0].replace("::_$u7b$$u7b$closure$u7d$$u7d$", "::{closure}")
        where = location.rsplit("/", 1)[-1].rsplit(":", 1)[0]
        functions[name] += counts[address]
        lines[f"{where:<22} {name}"] += counts[address]
    return functions, lines


def by_symbol(counts):
    _, symbols = read_elf(ELF)
    functions_sorted = sorted((addr, size, name) for name, addr, size, kind in symbols)
    functions = collections.Counter()
    for address, count in counts.items():
        owner = next((name for start, size, name in functions_sorted if start <= address < start + size),
                     "?")
        functions[owner] += count
    return functions, collections.Counter()


def main(argv):
    top = int(argv[1]) if len(argv) > 1 else 25
    if not os.path.exists(ELF):
        raise SystemExit(f"{ELF} is missing: run bench/target.sh first")
    counts = run_qemu()
    total = sum(counts.values())
    symbolizer = shutil.which("llvm-symbolizer")
    functions, lines = by_symbolizer(counts, symbolizer) if symbolizer else by_symbol(counts)
    print(f"instructions counted: {total} (from {START_SYMBOL or 'the start'} to {STOP_SYMBOL})")
    for title, table in (("by function", functions), ("by source line", lines)):
        if not table:
            continue
        print(f"\n{title}")
        for name, count in table.most_common(top):
            print(f"  {count:>11} {100 * count / total:5.1f}%  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
