#!/usr/bin/env python3
"""Turns the firmware's QEMU output and its ELF into the table bench/target.sh prints.

Usage: target_report.py FIRMWARE_ELF MEMORY_X QEMU_OUTPUT

The firmware prints one `kind key=value ...` record per line. Memory figures come from the ELF
itself (section headers and symbol sizes), with the flash and RAM regions read from memory.x, so
nothing beyond Python's standard library is needed. The last line printed is the
machine-readable summary; the exit status is non-zero when the run is incomplete or failed.
"""

import re
import struct
import sys

BUDGET_INSTRUCTIONS = 1_000_000
BUDGET_RAM_AND_STACK = 96 * 1024
BUDGET_LIBRARY_FLASH = 64 * 1024

SHF_ALLOC = 0x2
SHT_SYMTAB = 2
SHT_NOBITS = 8
STT_OBJECT = 1
STT_FUNC = 2


def read_elf(path):
    """Allocated sections as (name, address, size, occupies_file) and sized symbols as
    (name, address, size, kind)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise SystemExit(f"{path}: not a 32-bit little-endian ELF")
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    headers = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]

    def string(table_offset, index):
        end = data.index(b"\0", table_offset + index)
        return data[table_offset + index:end].decode("utf-8", "replace")

    names_offset = headers[shstrndx][4]
    sections = []
    symbols = []
    for name, kind, flags, addr, offset, size, link, _, _, entsize in headers:
        if flags & SHF_ALLOC and size:
            sections.append((string(names_offset, name), addr, size, kind != SHT_NOBITS))
        if kind == SHT_SYMTAB:
            strings_offset = headers[link][4]
            for i in range(size // entsize):
                sym_name, value, sym_size, info, _, _ = struct.unpack_from(
                    "<IIIBBH", data, offset + i * entsize)
                sym_kind = info & 0xF
                if sym_size and sym_kind in (STT_OBJECT, STT_FUNC):
                    symbols.append((string(strings_offset, sym_name), value & ~1, sym_size, sym_kind))
    return sections, symbols


def read_memory_x(path):
    """Regions of memory.x as {name: (origin, length)}."""
    regions = {}
    pattern = re.compile(r"(\w+)\s*:\s*ORIGIN\s*=\s*(0x[0-9a-fA-F]+|\d+)\s*,\s*LENGTH\s*=\s*(\d+)\s*([KM]?)")
    scale = {"": 1, "K": 1024, "M": 1024 * 1024}
    with open(path) as f:
        text = re.sub(r"/\*.*?\*/", "", f.read(), flags=re.S)
    for name, origin, length, unit in pattern.findall(text):
        regions[name] = (int(origin, 0), int(length) * scale[unit])
    return regions


def memory(elf_path, memory_x_path):
    sections, symbols = read_elf(elf_path)
    regions = read_memory_x(memory_x_path)

    def in_region(addr, name):
        origin, length = regions[name]
        return origin <= addr < origin + length

    ram_regions = [r for r in regions if r != "FLASH"]
    # Sections placed in RAM take RAM; those with initial values (.data) also take flash.
    static_ram = sum(size for _, addr, size, _ in sections if any(in_region(addr, r) for r in ram_regions))
    flash = sum(size for _, addr, size, in_file in sections
                if in_file and (in_region(addr, "FLASH") or any(in_region(addr, r) for r in ram_regions)))
    frames = sum(size for name, _, size, _ in symbols if "FRAMES_BLOB" in name)
    # Aliases (one body under two names) count once.
    unique = {(addr, size): name for name, addr, size, _ in symbols if in_region(addr, "FLASH")}
    library = sum(size for (_, size), name in unique.items() if "kestrel" in name)
    return {
        "sections": sections,
        "static_ram": static_ram,
        "flash_total": flash,
        "frames": frames,
        "flash": flash - frames,
        "library": library,
    }


def parse_log(path):
    """Records of the firmware output: {kind: [ {key: value} ]}, values as strings."""
    records = {}
    with open(path, errors="replace") as f:
        for line in f:
            words = line.split()
            if not words:
                continue
            fields = dict(w.split("=", 1) for w in words[1:] if "=" in w)
            if words[0] == "frame" and len(words) > 1:
                fields["index"] = words[1]
            records.setdefault(words[0], []).append(fields)
    return records


def one(records, kind):
    found = records.get(kind)
    if not found:
        raise SystemExit(f"firmware output has no '{kind}' record: the run did not finish")
    return found[-1]


def row(label, value, note=""):
    return f"  {label:<40} {value:>12}  {note}".rstrip()


def main(argv):
    if len(argv) != 4:
        raise SystemExit(__doc__)
    elf, memory_x, log = argv[1:]
    records = parse_log(log)
    mem = memory(elf, memory_x)
    config = one(records, "config")
    calibration = one(records, "calibration")
    per_frame = one(records, "per_frame")
    one(records, "stack")  # printed last: the firmware reached its end
    stages = {s["name"]: int(s["instructions_per_frame"]) for s in records.get("stage", [])}
    points = int(config["points"])

    total = int(per_frame["instructions"])
    # The budget configuration's figures; the profile variants after it run deeper frames.
    stack_peak = int(per_frame["stack_peak"])
    ram_and_stack = mem["static_ram"] + stack_peak
    out = []
    out.append("Kestrel on the STM32F405 (QEMU netduinoplus2, -icount shift=0)")
    out.append(
        f"  {config['frame']} frames, {points} points on a grid, LK window {config['window']}x{config['window']}, "
        f"max_level {config['max_level']} ({config['levels']} levels), {config['max_iterations']} iterations, "
        f"illumination {config['illumination']}, scene motion {config['motion']} px/frame")
    ipt = int(calibration["milli_instructions_per_tick"]) / 1000
    out.append(
        f"  SysTick calibration: {calibration['loop_instructions']} instructions = {calibration['ticks']} ticks "
        f"= {ipt:.3f} instructions/tick; ticks x 1000 / 21 is off by {calibration['error_ppm']} ppm")
    out.append("")
    out.append(f"  {'per frame (mean of ' + per_frame['frames'] + ' frames)':<40} {'instructions':>12}  note")
    for name, value in stages.items():
        note = f"{value // points} per point" if name == "track" else ""
        out.append(row(name, value, note))
    out.append(row("refill", "-", "no detector in the library yet"))
    ratio = total / BUDGET_INSTRUCTIONS
    out.append(row("total", total, f"budget {BUDGET_INSTRUCTIONS}: {ratio:.1f}x"))
    out.append(row("worst frame", per_frame["worst"]))
    out.append(row("points tracked (worst frame)", per_frame["tracked_min"], f"of {points}"))
    out.append(row("median flow error (worst frame)", per_frame["worst_error"] + " px", "tolerance 0.050"))
    out.append("")
    out.append(f"  {'memory':<40} {'bytes':>12}")
    out.append(row("static RAM (.data + .bss)", mem["static_ram"]))
    out.append(row("stack high-water mark", stack_peak, "boot to end of the budget run, printing included"))
    out.append(row("  of which the pipeline, below its caller", per_frame["pipeline_stack"], "pyramid + LK"))
    out.append(row("static RAM + stack", ram_and_stack, f"budget {BUDGET_RAM_AND_STACK}"))
    out.append(row("flash without the test frames", mem["flash"], "vector table, code, constants, .data image"))
    out.append(row("  of which Kestrel (symbol sizes)", mem["library"], f"budget {BUDGET_LIBRARY_FLASH}"))
    out.append(row("test frames in flash", mem["frames"], "stand-in for the camera"))
    out.append("")
    out.append(profile(records, points))
    out.append("  bad input (each must be refused, the frames after it still tracked)")
    for bad in records.get("bad_input", []):
        out.append(f"    {bad['case']:<14} -> {bad['outcome']}, quality {bad['quality']}")
    out.append("")
    print("\n".join(out))

    with open(log, errors="replace") as f:
        passed = any(line.strip() == "result pass" for line in f)
    print(
        f"instructions_per_frame={total} static_ram={mem['static_ram']} stack_peak={stack_peak} "
        f"flash={mem['flash']} tracks={per_frame['tracked_min']}")
    return 0 if passed else 1


def profile(records, points):
    """Where tracking spends its instructions, from the firmware's variant runs."""
    variants = {v["name"]: v for v in records.get("variant", [])}
    lines = [f"  {'tracking variants (same 11 frames)':<40} {'track/frame':>12}  per point, worst error"]
    for name, v in variants.items():
        desc = (f"{name} (w{v['window']} L{v['max_level']} it{v['max_iterations']} "
                f"{v['illumination']})")
        # The iteration-count variants stop every point before it converges: none is tracked.
        error = f"{v['worst_error']} px" if int(v["tracked_min"]) else "none tracked"
        lines.append(row(desc, v["track"], f"{v['track_per_point']}, {error}"))
    runs = [variants.get(k) for k in ("one_iteration", "two_iterations", "three_iterations")]
    if all(runs):
        # At level 0 with epsilon 0 every point runs exactly 1, 2 or 3 iterations. The first
        # computes the window's correlations with the template; a later one reuses them unless
        # the estimate moved to another integer pixel (the first step often does, the second
        # rarely).
        one, two, three = (int(r["track"]) / points for r in runs)
        lines.append(row("one template and its first iteration", round(one),
                         "per point and level: sample, Scharr, sums, correlations, step"))
        lines.append(row("second iteration", round(two - one), "per point, new correlations if moved"))
        lines.append(row("third iteration", round(three - two), "per point, mostly the same pixel"))
    lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
