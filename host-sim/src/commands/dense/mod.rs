//! `host-sim dense`: the library's grid flow between two frames, as CSV, a Middlebury `.flo`
//! field and the Middlebury colour picture.
//!
//! The grid and motion runners `dense` and `motion` share (runner.rs), the `.flo` field
//! (field.rs), the colour wheel (wheel.rs) and the motion overlay (picture.rs) live beside it.

pub mod field;
pub mod picture;
mod runner;
pub mod wheel;

pub use runner::*;

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use kestrel::dense::{DenseError, DenseParams, GridLayout, GridNode, NodeStatus};
use kestrel::lk::LkParams;
use kestrel::{Bound, ConfigError};

use super::{check_same_size, time_core, CommandError};
use crate::cli::values::{self, path};
use crate::io::csv::{CsvWriter, Fixed4};
use crate::io::images::{encode_rgb_png, read_grey};
use crate::io::json::one_line;
use crate::io::{AtomicFile, InputError, OutputError};
use field::FlowField;
use serde_json::json;
use wheel::flow_picture;

/// Columns of grid.csv: the contract's five, then the node's status by name.
pub const COLUMNS: [&str; 6] = ["x", "y", "dx", "dy", "ok", "status"];

/// `host-sim dense`: its flags, their rules and its usage text.
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(
    help_template = crate::cli::TEMPLATE,
    term_width = 100,
    about = "flow at every node of a grid, as CSV, a Middlebury .flo field and picture",
    before_help = "host-sim dense: the library's grid flow from frame A to frame B: LK at every node of a
regular grid, each node checked for texture, convergence and residual, the rest filled from
their neighbours, then each measured node averaged with the neighbours that move alike.",
    after_help = "grid.csv columns:
  x,y      the node centre in A: (cell/2 + i*cell, cell/2 + j*cell)
  dx,dy    its flow from A to B, px (0 when unknown; filled from the neighbours when filled;
           smoothed when measured, unless --smooth-gate 0 or --smooth-passes 0)
  ok       1 when measured; 0 otherwise
  status   tracked, low_texture, residual (the window does not match), lost (not converged
           or left the frame) or filled

Coordinates are pixels from the centre of the top-left pixel, x right, y down.
Nothing is written unless every step succeeds.

Exit status: 0 success; 1 unreadable or malformed input, or an output that cannot be written;
2 bad command line."
)]
pub struct DenseOptions {
    /// first frame: PNG, JPEG, PGM or BMP, converted to BT.601 grey
    #[arg(long, value_name = "A", value_parser = path)]
    pub prev: PathBuf,
    /// second frame, the same size as A
    #[arg(long, value_name = "B", value_parser = path)]
    pub next: PathBuf,
    /// one row per grid node, row by row (see below)
    #[arg(long, value_name = "grid.csv", value_parser = path)]
    pub out: PathBuf,
    /// the flow at every pixel of A, interpolated from the grid, as a Middlebury .flo file
    /// (unknown flow is 1e10)
    #[arg(long, value_name = "F.flo", value_parser = path)]
    pub flo: Option<PathBuf>,
    /// the Middlebury colour picture of that flow: hue is the direction, colour strength the
    /// speed up to the largest in the picture, black is unknown; a legend wheel sits in the
    /// top-right corner
    #[arg(long, value_name = "F.png", value_parser = path)]
    pub png: Option<PathBuf>,
    #[command(flatten)]
    pub grid: GridFlags,
    /// average each measured node with the measured neighbours whose flow is within PX (0 to
    /// 8) of its own (a local affine fit); 0 leaves the measurements alone
    #[arg(long, value_name = "PX", default_value_t = kestrel::dense::SMOOTH_GATE, value_parser = smooth_gate)]
    pub smooth_gate: f32,
    /// passes of that fit, each over the nodes the last one smoothed and reaching a node
    /// further, 0 to 8; 0 leaves the measurements alone
    #[arg(long, value_name = "N", default_value_t = kestrel::dense::SMOOTH_PASSES, value_parser = smooth_passes)]
    pub smooth_passes: u8,
    /// run the core (build both pyramids, compute the grid, smooth it) N times, N >= 1
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = values::repeat)]
    pub repeat: usize,
    /// write {"nodes": n, "repeat": N, "median_core_seconds": t}; decoding is not timed
    #[arg(long, value_name = "S.json", value_parser = path)]
    pub stats: Option<PathBuf>,
}

/// The grid and LK flags shared by `dense` and `motion`, over the dense defaults.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::Args)]
pub struct GridFlags {
    /// grid spacing in px, 1 to the frame's smaller side
    #[arg(long, value_name = "N", default_value_t = 8, value_parser = cell)]
    pub cell: usize,
    /// LK window side in px, odd, 3 to 63
    #[arg(long, value_name = "N", default_value_t = 9, value_parser = values::window)]
    pub window: usize,
    /// coarsest pyramid level, 0 to 7
    #[arg(long, value_name = "L", default_value_t = 3, value_parser = values::levels)]
    pub levels: usize,
}

impl GridFlags {
    /// `defaults` with these flags in place.
    pub fn params(&self, defaults: DenseParams) -> DenseParams {
        DenseParams {
            cell: self.cell,
            lk: LkParams {
                window: self.window,
                max_level: self.levels,
                ..defaults.lk
            },
            ..defaults
        }
    }
}

/// Cells up to the largest frame; the frame's own size is checked once it is read.
fn cell(text: &str) -> Result<usize, String> {
    let range = |n| (1..=kestrel::MAX_DIMENSION as i64).contains(&n);
    values::whole(text, range, "must be between 1 and 4096").map(|n| n as usize)
}

/// A smoothing gate: 0 to 8 px.
fn smooth_gate(text: &str) -> Result<f32, String> {
    let range = |v: f64| (0.0..=8.0).contains(&v);
    values::number(text, range, "must be between 0 and 8 px").map(|v| v as f32)
}

/// Smoothing passes: 0 to 8.
fn smooth_passes(text: &str) -> Result<u8, String> {
    values::whole(text, |n| (0..=8).contains(&n), "must be between 0 and 8").map(|n| n as u8)
}

/// The outputs, created before any work so an unwritable path fails fast.
struct Outputs {
    csv: AtomicFile,
    flo: Option<AtomicFile>,
    png: Option<AtomicFile>,
    stats: Option<AtomicFile>,
}

impl Outputs {
    fn create(options: &DenseOptions) -> Result<Self, OutputError> {
        let optional = |path: &Option<PathBuf>| path.as_deref().map(AtomicFile::create).transpose();
        Ok(Self {
            csv: AtomicFile::create(&options.out)?,
            flo: optional(&options.flo)?,
            png: optional(&options.png)?,
            stats: optional(&options.stats)?,
        })
    }

    /// Commits every output, once all were written.
    fn commit(self) -> Result<(), OutputError> {
        self.csv.commit()?;
        for file in [self.flo, self.png, self.stats].into_iter().flatten() {
            file.commit()?;
        }
        Ok(())
    }
}

/// Runs `dense`. Nothing is written unless every step succeeds.
pub fn run(options: &DenseOptions) -> Result<(), CommandError> {
    let mut outputs = Outputs::create(options)?;
    let prev = read_grey(&options.prev)?;
    let next = read_grey(&options.next)?;
    check_same_size(&options.prev, &options.next, &prev, &next)?;
    let size = (prev.width, prev.height);
    let params = options.grid.params(DenseParams::default());
    let refused = |e| refused(e, &params, &options.prev, size);
    let smoothing = (options.smooth_gate > 0.0 && options.smooth_passes > 0).then_some(Smoothing {
        gate: options.smooth_gate,
        passes: options.smooth_passes,
    });
    let mut runner = DenseRunner::new(params, size.0, size.1)
        .map_err(refused)?
        .with_smoothing(smoothing);
    let ((), seconds) = time_core(options.repeat, || {
        runner.compute(&prev, &next).map(|_| ()).map_err(refused)
    })?;
    let (layout, nodes) = (runner.layout(), runner.nodes());

    let csv = &mut outputs.csv;
    write_grid_csv(&mut *csv, layout, nodes).map_err(|e| csv.write_error(&e))?;
    let field = (options.flo.is_some() || options.png.is_some())
        .then(|| FlowField::from_grid(layout, nodes));
    if let (Some(file), Some(field)) = (&mut outputs.flo, &field) {
        file.write_all(&field.to_flo())
            .map_err(|e| file.write_error(&e))?;
    }
    if let (Some(file), Some(field)) = (&mut outputs.png, &field) {
        let picture = flow_picture(field);
        let (width, height) = (picture.width() as usize, picture.height() as usize);
        let bytes = encode_rgb_png(width, height, picture.as_raw())
            .map_err(|problem| OutputError::new(file.target(), problem))?;
        file.write_all(&bytes).map_err(|e| file.write_error(&e))?;
    }
    if let Some(file) = &mut outputs.stats {
        let summary = one_line(&json!({
            "nodes": layout.len(),
            "repeat": options.repeat,
            "median_core_seconds": seconds,
        }));
        file.write_all(summary.as_bytes())
            .map_err(|e| file.write_error(&e))?;
    }
    outputs.commit()?;
    Ok(())
}

/// The error for frames of `input` (`width` x `height`) the library refused, naming the flag or
/// the input at fault.
pub(crate) fn refused(
    error: RunError,
    params: &DenseParams,
    input: &Path,
    (width, height): (usize, usize),
) -> CommandError {
    match error {
        RunError::Config(ConfigError {
            field: "cell" | "grid.cell",
            bound: Bound::Range { .. },
        }) => CommandError::Processing(format!(
            "--cell: {} px is larger than the {width}x{height} frames",
            params.cell
        )),
        RunError::Dense(DenseError::FrameTooSmall) => CommandError::Input(InputError::file(
            input,
            format!(
                "frame is {width}x{height}, too small for {} pyramid levels with a {} px window (use fewer --levels)",
                params.lk.max_level, params.lk.window
            ),
        )),
        other => CommandError::Processing(format!(
            "{}: the library refused the frames: {other}",
            input.display()
        )),
    }
}

/// The name of a status in grid.csv's `status` column.
pub fn status_name(status: NodeStatus) -> &'static str {
    match status {
        NodeStatus::Tracked => "tracked",
        NodeStatus::LowTexture => "low_texture",
        NodeStatus::Residual => "residual",
        NodeStatus::Lost => "lost",
        NodeStatus::Filled => "filled",
    }
}

/// One row per node, row by row: its centre, its flow (zero when unknown), whether it was
/// measured, and its status.
fn write_grid_csv(out: impl Write, layout: &GridLayout, nodes: &[GridNode]) -> io::Result<()> {
    let mut csv = CsvWriter::new(out, &COLUMNS)?;
    for (index, node) in nodes.iter().enumerate().take(layout.len()) {
        let (col, row) = layout.node(index);
        let (x, y) = layout.centre(col, row);
        let (dx, dy) = node.flow.to_f32();
        csv.record((
            x,
            y,
            Fixed4(f64::from(dx)),
            Fixed4(f64::from(dy)),
            u8::from(node.is_valid()),
            status_name(node.status),
        ))?;
    }
    csv.finish()?.flush()
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::Point;

    #[test]
    fn rows_name_the_centre_flow_and_status() {
        let layout = GridLayout::new(16, 8, 8).unwrap();
        let nodes = [
            GridNode::tracked(Point::from_f32(1.5, -0.25)),
            GridNode::invalid(NodeStatus::LowTexture),
        ];
        let mut text = Vec::new();
        write_grid_csv(&mut text, &layout, &nodes).unwrap();
        assert_eq!(
            String::from_utf8(text).unwrap(),
            "x,y,dx,dy,ok,status\n4,4,1.5000,-0.2500,1,tracked\n12,4,0.0000,0.0000,0,low_texture\n"
        );
    }
}
