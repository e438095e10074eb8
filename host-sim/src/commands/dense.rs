//! `host-sim dense`: the library's grid flow between two frames, as CSV, a Middlebury `.flo`
//! field and the Middlebury colour picture.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use kestrel::dense::grid::{DenseParams, GridLayout, GridNode, NodeStatus};
use kestrel::dense::DenseError;

use super::{check_same_size, time_core, CommandError};
use crate::dense::field::FlowField;
use crate::dense::wheel::flow_picture;
use crate::dense::{DenseRunner, RunError};
use crate::io::csv::{CsvWriter, Fixed4};
use crate::io::images::{encode_rgb_png, read_grey};
use crate::io::json::JsonObject;
use crate::io::{AtomicFile, InputError, OutputError};

/// Columns of grid.csv: the contract's five, then the node's status by name.
pub const COLUMNS: [&str; 6] = ["x", "y", "dx", "dy", "ok", "status"];

/// Everything `dense` needs, validated by the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseOptions {
    /// The first frame.
    pub prev: PathBuf,
    /// The second frame.
    pub next: PathBuf,
    /// CSV of the grid.
    pub out: PathBuf,
    /// Where to write the full-resolution `.flo` field, if anywhere.
    pub flo: Option<PathBuf>,
    /// Where to write the colour picture, if anywhere.
    pub png: Option<PathBuf>,
    /// Grid and tracking parameters.
    pub params: DenseParams,
    /// How many times the core runs (at least 1).
    pub repeat: usize,
    /// Where to write the timing summary, if anywhere.
    pub stats: Option<PathBuf>,
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
    let refused = |e| refused(e, &options.params, &options.prev, size);
    let mut runner = DenseRunner::new(options.params, size.0, size.1).map_err(refused)?;
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
        let bytes = encode_rgb_png(picture.width, picture.height, &picture.rgb)
            .map_err(|problem| OutputError::new(file.target(), problem))?;
        file.write_all(&bytes).map_err(|e| file.write_error(&e))?;
    }
    if let Some(file) = &mut outputs.stats {
        let summary = JsonObject::new()
            .integer("nodes", layout.len() as u64)
            .integer("repeat", options.repeat as u64)
            .number("median_core_seconds", seconds)
            .finish();
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
        RunError::Dense(DenseError::CellTooLarge) => CommandError::Processing(format!(
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
        csv.record(&[
            &x,
            &y,
            &Fixed4(f64::from(dx)),
            &Fixed4(f64::from(dy)),
            &u8::from(node.is_valid()),
            &status_name(node.status),
        ])?;
    }
    csv.into_inner().flush()
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
