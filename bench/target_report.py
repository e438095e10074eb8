#!/usr/bin/env python3
"""Turns the firmware's QEMU output and its ELF into the table bench/target.sh prints.

Usage: target_report.py FIRMWARE_ELF MEMORY_X QEMU_OUTPUT

The firmware prints one `kind key=value ...` record per line. Memory figures come from the ELF
itself (section headers and symbol sizes), with the flash and RAM regions read from memory.x, so
nothing beyond Python's standard library is needed; with the toolchain's llvm-objdump (rustup
component llvm-tools) it also counts the library's code that LTO built into other functions. The last line printed is the
machine-readable summary; the exit status is non-zero when the run is incomplete or failed.
"""

import os
import re
import struct
import subprocess
import sys

SENSOR_BUDGET_INSTRUCTIONS = 420_000
# The dense grid and its motion boxes together (grid, dominant motion, mask, regions, boxes).
BUDGET_DENSE_INSTRUCTIONS = 2_000_000
BUDGET_INSTRUCTIONS = 1_000_000
BUDGET_TRACKER_STATE = 64 * 1024
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


def objdump():
    """The toolchain's llvm-objdump (rustup component llvm-tools), or None."""
    try:
        sysroot = subprocess.run(["rustc", "--print", "sysroot"], capture_output=True,
                                 text=True, check=True).stdout.strip()
        host = subprocess.run(["rustc", "-vV"], capture_output=True, text=True,
                              check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    triple = next((l.split()[1] for l in host.splitlines() if l.startswith("host:")), "")
    path = os.path.join(sysroot, "lib", "rustlib", triple, "bin", "llvm-objdump")
    return path if os.access(path, os.X_OK) else None


def inlined_library_bytes(elf_path, source_root):
    """Bytes of code inside other crates' functions whose source line is the library's (LTO
    and generics put Kestrel's code there: a tracker of N tracks is built into its caller).
    Counted by each instruction's innermost line; the core helpers that code inlines in turn
    are not counted, so this is a lower bound. None without llvm-objdump."""
    tool = objdump()
    if tool is None:
        return None
    listing = subprocess.run([tool, "-d", "-l", "--no-show-raw-insn", elf_path],
                             capture_output=True, text=True, check=True).stdout
    header = re.compile(r"^[0-9a-f]+ <(.*)>:$")
    instruction = re.compile(r"^\s*([0-9a-f]+):\s")
    library_source = os.path.join(source_root, "src") + os.sep
    total, symbol, line, previous = 0, "", "", None
    for text in listing.splitlines():
        if m := header.match(text):
            symbol, previous = m.group(1), None
        elif text.startswith("; /"):
            line = text
        elif m := instruction.match(text):
            address = int(m.group(1), 16)
            if previous is not None and 0 < address - previous[0] <= 4 and previous[1]:
                total += address - previous[0]
            ours = library_source in line and "kestrel" not in symbol
            previous = (address, ours)
    return total


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
    mavlink = sum(size for (_, size), name in unique.items() if "mavlink" in name and "kestrel" not in name)
    # The px4flow crate and firmware/src/px4flow.rs, into which LTO inlines the matcher.
    px4flow = sum(size for (_, size), name in unique.items() if "px4flow" in name)
    return {
        "sections": sections,
        "static_ram": static_ram,
        "flash_total": flash,
        "frames": frames,
        "flash": flash - frames,
        "library": library,
        "mavlink": mavlink,
        "px4flow": px4flow,
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
    return f"  {label:<44} {value:>12}  {note}".rstrip()


def main(argv):
    if len(argv) != 4:
        raise SystemExit(__doc__)
    elf, memory_x, log = argv[1:]
    records = parse_log(log)
    mem = memory(elf, memory_x)
    config = one(records, "config")
    calibration = one(records, "calibration")
    state = one(records, "memory")
    prime = one(records, "prime")
    per_frame = one(records, "per_frame")
    refills = one(records, "refills")
    tolerances = one(records, "tolerances")
    one(records, "stack")  # printed last: the firmware reached its end
    stages = {s["name"]: int(s["instructions_per_frame"]) for s in records.get("stage", [])}
    frames = int(per_frame["frames"])

    budget = int(per_frame["instructions"])
    stack_peak = int(per_frame["stack_peak"])
    ram_and_stack = mem["static_ram"] + stack_peak
    followed = int(per_frame["followed"]) / max(frames, 1)
    out = []
    out.append("Kestrel on the STM32F405 (QEMU netduinoplus2, -icount shift=0)")
    out.append(
        f"  {config['frame']} frames ({config['frames']}), tracker of {config['max_tracks']} tracks "
        f"(refill below {config['refill_below']}, Shi-Tomasi on level {config['detect_level']}), "
        f"LK window {config['window']}x{config['window']}, max_level {config['max_level']} "
        f"({config['levels']} levels), {config['max_iterations']} iterations, {config['illumination']}")
    out.append(
        f"  dense grid of {config['cell']} px cells; camera motion {config['motion']} px/frame, "
        f"object {config['object_motion']} px/frame")
    ipt = int(calibration["milli_instructions_per_tick"]) / 1000
    out.append(
        f"  SysTick calibration: {calibration['loop_instructions']} instructions = {calibration['ticks']} ticks "
        f"= {ipt:.3f} instructions/tick; ticks x 1000 / 21 is off by {calibration['error_ppm']} ppm")
    out.append("")
    out.append(f"  {'per frame (mean of ' + str(frames) + ' frames)':<44} {'instructions':>12}  note")
    out.append(row("pyramid", stages["pyramid"]))
    out.append(row("tracking", stages["track"],
                   f"forward + backward LK and gates, {followed:.1f} tracks: "
                   f"{stages['track'] / max(followed, 1):.0f} per track"))
    out.append(row("refill (detection)", stages["refill"],
                   f"ran in {refills['frames']} of {frames} frames, "
                   f"{refills['instructions_per_refill']} each"))
    ratio = budget / BUDGET_INSTRUCTIONS
    out.append(row("budget: pyramid + tracking + refill", budget,
                   f"budget {BUDGET_INSTRUCTIONS}: {ratio:.1f}x"))
    out.append(row("  worst frame", per_frame["worst"]))
    out.append(row("ego-motion + OPTICAL_FLOW_RAD + MAVLink", stages["ego"],
                   "homography RANSAC on the tracks"))
    out.append(row("dense grid", stages["dense"], "LK at 300 nodes and the fill"))
    out.append(row("motion boxes", stages["boxes"], "mask and regions against the tracks' homography"))
    dense = int(stages["dense"]) + int(stages["boxes"])
    out.append(row("  dense grid + motion boxes", dense,
                   f"budget {BUDGET_DENSE_INSTRUCTIONS}: {dense / BUDGET_DENSE_INSTRUCTIONS:.2f}x"))
    out.append(row("whole pipeline", per_frame["all_stages"]))
    out.append(row("  worst frame", per_frame["worst_all_stages"]))
    out.append(row("first frame (pyramid + detection)", prime["instructions"],
                   f"{prime['tracks']} tracks started"))
    out.append("")
    out.append(f"  {'checks, every frame (worst frame)':<44} {'measured':>12}  must be")
    out.append(row("live tracks", per_frame["tracks_min"],
                   f">= {tolerances['live_tracks']} ({per_frame['tracks']} after the last frame)"))
    out.append(row("median track displacement error", per_frame["track_error_worst"] + " px",
                   f"<= {tolerances['track_error']} px"))
    out.append(row("OPTICAL_FLOW_RAD flow error", per_frame["flow_error_worst"] + " rad",
                   f"<= {tolerances['flow_rad']} rad ({tolerances['flow_px']} px at the principal point)"))
    out.append(row("best motion box IoU with the object", per_frame["box_iou_min"],
                   f">= {tolerances['box_iou']}"))
    out.append(row("boxes away from the object (all frames)", per_frame["false_boxes"], "0"))
    out.append("")
    out.append(f"  {'memory':<44} {'bytes':>12}")
    out.append(row("tracker state", state["tracker_state"],
                   f"budget {BUDGET_TRACKER_STATE}: both pyramids ({state['tracker_storage']} with "
                   f"FAST's rows), tracks ({state['tracker_struct']}), scratch, candidates"))
    out.append(row("dense grid and boxes state", state["dense_state"]))
    out.append(row("ego-motion state", state["ego_state"], "RANSAC pairs and inliers, MAVLink frame"))
    out.append(row("static RAM (.data + .bss)", mem["static_ram"]))
    out.append(row("stack high-water mark", stack_peak, "boot to the end of the run, printing included"))
    out.append(row("  start-up", per_frame["boot_stack"],
                   "the pipeline is made on the stack, then moved to its static"))
    out.append(row("  frames", per_frame["frames_stack"]))
    out.append(row("  of which the pipeline, below its caller", per_frame["pipeline_stack"]))
    out.append(row("static RAM + stack", ram_and_stack, f"budget {BUDGET_RAM_AND_STACK}"))
    out.append(row("flash without the test frames", mem["flash"], "vector table, code, constants, .data image"))
    out.append(row("  of which Kestrel (symbol sizes)", mem["library"], f"budget {BUDGET_LIBRARY_FLASH}"))
    inlined = inlined_library_bytes(elf, os.path.dirname(os.path.abspath(memory_x)))
    out.append(row("  and Kestrel's code inside other functions", "n/a" if inlined is None else inlined,
                   "by line info, at least: LTO-inlined and generic code (llvm-tools)"))
    out.append(row("  of which the mavlink crate", mem["mavlink"]))
    out.append(row("  of which the PX4FLOW baseline", mem["px4flow"], "px4flow crate and its runner"))
    out.append(row("test frames in flash", mem["frames"], "stand-in for the camera"))
    out.append("")
    sensor = one(records, "sensor")
    sensor_frames = records.get("sensor_frame", [])
    sensor_ego = sum(int(f["ego"]) for f in sensor_frames) // max(len(sensor_frames), 1)
    out.append(f"  {'flow-sensor preset (mean of ' + sensor['frames'] + ' frames)':<44} {'instructions':>12}  note")
    out.append(row("pyramid + tracking + refill", int(sensor["instructions_per_frame"]) - sensor_ego,
                   f"TrackerConfig::flow_sensor(), {sensor['tracks']} tracks after the last frame"))
    out.append(row("similarity fit + OPTICAL_FLOW_RAD + MAVLink", sensor_ego))
    out.append(row("whole sensor frame", sensor["instructions_per_frame"],
                   f"budget {SENSOR_BUDGET_INSTRUCTIONS}: {int(sensor['instructions_per_frame']) / SENSOR_BUDGET_INSTRUCTIONS:.2f}x"))
    out.append(row("  worst frame", sensor["worst"]))
    link = one(records, "link")
    out.append(row("MAVLink sending per readout", link["instructions_per_frame"],
                   f"beside the frame: HEARTBEAT/s, OPTICAL_FLOW_RAD, OPTICAL_FLOW; worst {link['worst']}"))
    full = one(records, "link_check")
    out.append(row("  port busy: frames kept, dropped", f"{full['whole']}, {full['dropped']}",
                   f"boot check: {full['drained']} bytes drained whole, {full['gaps']} sequence gaps"))
    out.append(row("OPTICAL_FLOW_RAD flow error (worst frame)", sensor["flow_error_px"] + " px",
                   "<= 0.050 px at the principal point"))
    for bad in records.get("sensor_bad_input", []):
        out.append(f"    {bad['case']:<14} -> {bad['outcome']}, quality {bad['quality']} "
                   f"(MAVLink frame: {bad['mavlink_quality']})")
    out.append("")
    out.append(profile(records))
    out.append(baseline(records))
    out.append("  bad input (each must be refused with quality 0, the frames after it still processed)")
    for bad in records.get("bad_input", []):
        out.append(f"    {bad['case']:<14} -> {bad['outcome']}, quality {bad['quality']} "
                   f"(MAVLink frame: {bad['mavlink_quality']})")
    out.append("")
    print("\n".join(out))

    with open(log, errors="replace") as f:
        passed = any(line.strip() == "result pass" for line in f)
    print(
        f"instructions_per_frame={budget} static_ram={mem['static_ram']} stack_peak={stack_peak} "
        f"flash={mem['flash']} tracks={per_frame['tracks']} "
        f"sensor_instructions_per_frame={sensor['instructions_per_frame']} "
        f"sensor_flow_error_px={sensor['flow_error_px']} "
        f"pipeline_instructions_per_frame={per_frame['all_stages']} kestrel_flash={mem['library']} "
        f"dense_instructions_per_frame={dense} "
        f"kestrel_inlined_flash={'n/a' if inlined is None else inlined}")
    return 0 if passed else 1


def profile(records):
    """Where LK spends its instructions, from the firmware's variant runs."""
    variants = {v["name"]: v for v in records.get("variant", [])}
    lines = [f"  {'LK variants (track_points, last pair, 100 points)':<44} {'instructions':>12}  "
             "per point, tracked, median error"]
    for name, v in variants.items():
        desc = (f"{name} (w{v['window']} L{v['max_level']} it{v['max_iterations']} "
                f"{v['illumination']})")
        # The iteration-count variants stop most points before they converge.
        error = f"{v['median_error']} px" if int(v["tracked"]) > 10 else "not converged"
        lines.append(row(desc, v["track"], f"{v['track_per_point']}, {v['tracked']}, {error}"))
    runs = [variants.get(k) for k in ("one_iteration", "two_iterations", "three_iterations")]
    if all(runs):
        # At level 0 with epsilon 0 every point runs exactly 1, 2 or 3 iterations. The first
        # computes the window's correlations with the template; a later one reuses them unless
        # the estimate moved to another integer pixel.
        one, two, three = (int(r["track_per_point"]) for r in runs)
        lines.append(row("one template and its first iteration", one,
                         "per point and level: sample, Scharr, sums, correlations, step"))
        lines.append(row("second iteration", two - one, "per point, new correlations if moved"))
        lines.append(row("third iteration", three - two, "per point, mostly the same pixel"))
    lines.append("")
    return "\n".join(lines)


def baseline(records):
    """PX4FLOW's block matching on the same frame pairs (firmware/src/px4flow.rs)."""
    found = records.get("px4flow")
    header = f"  {'PX4FLOW baseline, per frame pair':<44} {'instructions':>12}  note"
    if not found:
        return "\n".join([header, "    not run: the firmware printed no 'px4flow' record", ""])
    p = found[-1]
    label = f"SAD block matching, 25 blocks, +-{p['search_radius']} px"
    return "\n".join([
        header,
        row(label, p["instructions_per_frame"],
            f"USADA8; mean of {p['pairs']} pairs"),
        row("  mean flow, px/frame", f"{p['flow_x']},{p['flow_y']}",
            f"the camera moves {records['config'][-1]['motion']}"),
        row("  worst pair's error", p["flow_error_px"] + " px",
            "distance from the camera's motion; the object crosses the crop"),
        row("  lowest quality", p["quality"], f"fewest valid blocks {p['valid_blocks']} of 25"),
        "",
    ])


if __name__ == "__main__":
    sys.exit(main(sys.argv))
