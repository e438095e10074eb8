//! Sets `cfg(kestrel_dsp)` on targets with the Cortex-M4/M7 DSP instructions (USADA8, UHADD8,
//! SMLAD), so that `src/dsp.rs` emits them.
//!
//! `cfg(target_feature = "dsp")` would say so directly, but `dsp` is an unstable target
//! feature and stable rustc leaves unstable features out of `cfg`: for `thumbv7em-none-eabihf`,
//! rustc 1.95 sets no `target_feature` at all (nightly sets `dsp`). So the target's name
//! decides: every `thumbv7em-*` target is ARMv7E-M, which always has the DSP extension. Any
//! other ARM target whose `cfg` lists `dsp` (on nightly) qualifies too.

use std::env;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(kestrel_dsp)");
    println!("cargo::rerun-if-changed=build.rs");
    let var = |name: &str| env::var(name).unwrap_or_default();
    let arm = var("CARGO_CFG_TARGET_ARCH") == "arm";
    let armv7em = var("TARGET").starts_with("thumbv7em-");
    let dsp_feature = var("CARGO_CFG_TARGET_FEATURE")
        .split(',')
        .any(|feature| feature == "dsp");
    if arm && (armv7em || dsp_feature) {
        println!("cargo::rustc-cfg=kestrel_dsp");
    }
}
