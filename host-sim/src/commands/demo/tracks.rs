//! The demo's tracker section: trails over every frame, a contact sheet, tracks.csv, and how
//! well the tracks kept to the ground truth.

use std::collections::BTreeMap;
use std::path::Path;

use kestrel::track::FrameReport;

use super::Scenario;
use crate::commands::track::{frame_picture_name, write_error, write_rows, COLUMNS};
use crate::commands::CommandError;
use crate::io::csv::CsvWriter;
use crate::io::images::write_rgb_png;
use crate::io::{create_output_dir, AtomicFile};
use crate::tracking::{config_for, track_sequence};
use crate::viz::{canvas, contact_sheet, Trails};

/// Tracks aimed for.
const MAX_TRACKS: usize = 100;
/// Every how many frames the contact sheet takes one.
const SHEET_STEP: usize = 5;
/// Tiles per row of the contact sheet.
const SHEET_COLUMNS: usize = 4;
/// Colour of the objects' outlines.
const OUTLINE: image::Rgb<u8> = image::Rgb([255, 255, 255]);

/// Runs the tracker on the scenario and writes into `dir`: `trails/NNNNNN.png` for every frame,
/// `contact_sheet.png` and `tracks.csv`.
pub fn run(scenario: &Scenario, dir: &Path) -> Result<Vec<String>, CommandError> {
    let trails_dir = dir.join("trails");
    create_output_dir(&trails_dir)?;
    let csv_path = dir.join("tracks.csv");
    let mut csv = CsvWriter::new(AtomicFile::create(&csv_path)?, &COLUMNS)
        .map_err(|e| write_error(&csv_path, &e))?;
    let mut trails = Trails::new();
    let mut sheet = Vec::new();
    let mut stats = Stats::default();

    let frames = scenario.frames.iter().cloned().map(Ok::<_, CommandError>);
    let configure = |width, height| config_for(width, height, MAX_TRACKS);
    track_sequence(frames, configure, |tracked| {
        write_rows(&mut csv, tracked).map_err(|e| write_error(&csv_path, &e))?;
        trails.update(tracked.tracks);
        let mut picture = trails.draw(tracked.frame);
        outline_objects(scenario, tracked.index, &mut picture);
        write_rgb_png(
            &trails_dir.join(frame_picture_name(tracked.index)),
            &picture,
        )?;
        if tracked.index % SHEET_STEP == 0 {
            sheet.push(picture);
        }
        stats.add(
            scenario,
            tracked.index,
            tracked.tracks,
            &tracked.report,
            tracked.seconds,
        );
        Ok(())
    })?;
    csv.finish()
        .map_err(|e| write_error(&csv_path, &e))?
        .commit()?;
    write_rgb_png(
        &dir.join("contact_sheet.png"),
        &contact_sheet(&sheet, SHEET_COLUMNS, 2),
    )?;
    Ok(stats.summary(scenario.frames.len()))
}

/// Draws where the scene's objects are in frame `index`, from the ground truth, so that the
/// pictures show which trails ride on them.
fn outline_objects(scenario: &Scenario, index: usize, picture: &mut image::RgbImage) {
    let warp = scenario.sequence.homography(index);
    for object in &scenario.sequence.scene().objects {
        let (cx, cy) = object.centre(index as f64);
        let (hw, hh) = object.half_size;
        let corners = [(-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh)].map(|(dx, dy)| {
            let (x, y) = warp.apply(cx + dx, cy + dy);
            (x as f32, y as f32)
        });
        for (i, &a) in corners.iter().enumerate() {
            let b = corners[(i + 1) % corners.len()];
            canvas::line(picture, a, b, OUTLINE, 0.7);
        }
    }
}

/// What the demo reports about the tracks.
#[derive(Debug, Default)]
struct Stats {
    /// Frame and position where each id was born.
    births: BTreeMap<u32, (usize, (f64, f64))>,
    /// Live tracks after each frame.
    live: Vec<usize>,
    /// Ids alive in frame 0, and how many of them are alive in the latest frame.
    first_ids: Vec<u32>,
    survivors: usize,
    /// Errors of the latest frame's tracks against the ground truth, px.
    errors: Vec<f64>,
    /// Library time per frame, seconds.
    seconds: Vec<f64>,
    /// Sums of the frame reports.
    totals: FrameReport,
}

impl Stats {
    fn add(
        &mut self,
        scenario: &Scenario,
        index: usize,
        tracks: &[kestrel::track::Track],
        report: &FrameReport,
        seconds: f64,
    ) {
        let xy = |t: &kestrel::track::Track| -> (f64, f64) {
            (t.position.x.to_num(), t.position.y.to_num())
        };
        for track in tracks {
            self.births.entry(track.id).or_insert((index, xy(track)));
        }
        if index == 0 {
            self.first_ids = tracks.iter().map(|t| t.id).collect();
        }
        self.survivors = tracks
            .iter()
            .filter(|t| self.first_ids.contains(&t.id))
            .count();
        self.errors = tracks
            .iter()
            .map(|t| {
                let (born, at) = self.births[&t.id];
                scenario.sequence.distance_to_truth(born, at, index, xy(t))
            })
            .collect();
        self.live.push(tracks.len());
        self.seconds.push(seconds);
        self.totals.dropped_lost += report.dropped_lost;
        self.totals.dropped_residual += report.dropped_residual;
        self.totals.dropped_appearance += report.dropped_appearance;
        self.totals.dropped_relocation += report.dropped_relocation;
        self.totals.dropped_out_of_frame += report.dropped_out_of_frame;
        self.totals.dropped_fb += report.dropped_fb;
        if index > 0 {
            self.totals.added += report.added;
            self.totals.refused += report.refused;
        }
    }

    fn summary(mut self, frames: usize) -> Vec<String> {
        let last = frames.saturating_sub(1);
        self.errors.sort_by(f64::total_cmp);
        let n = self.errors.len().max(1) as f64;
        let mean = self.errors.iter().sum::<f64>() / n;
        let median = self
            .errors
            .get(self.errors.len() / 2)
            .copied()
            .unwrap_or(0.0);
        let within = self.errors.iter().filter(|&&e| e <= 1.0).count() as f64 / n;
        let first = self.first_ids.len().max(1);
        let ms = |s: f64| s * 1000.0;
        let mean_seconds = self.seconds.iter().sum::<f64>() / self.seconds.len().max(1) as f64;
        let slowest = self.seconds.iter().copied().fold(0.0, f64::max);
        let t = &self.totals;
        vec![
            format!(
                "live tracks per frame: min {}, mean {:.1}",
                self.live.iter().min().copied().unwrap_or(0),
                self.live.iter().sum::<usize>() as f64 / self.live.len().max(1) as f64
            ),
            format!(
                "survival: {} of the {} tracks of frame 0 still followed in frame {last} ({:.0}%)",
                self.survivors,
                self.first_ids.len(),
                100.0 * self.survivors as f64 / first as f64
            ),
            format!(
                "error against the ground truth in frame {last}: mean {mean:.2} px, median \
                 {median:.2} px, {:.0}% within 1 px ({} tracks)",
                100.0 * within,
                self.errors.len()
            ),
            format!(
                "dropped: {} lost, {} out of frame, {} residual, {} appearance, {} relocation, {} \
                 forward-backward; {} started after frame 0, {} corners refused at birth",
                t.dropped_lost,
                t.dropped_out_of_frame,
                t.dropped_residual,
                t.dropped_appearance,
                t.dropped_relocation,
                t.dropped_fb,
                t.added,
                t.refused
            ),
            format!(
                "library time per frame: {:.2} ms mean, {:.2} ms slowest (this machine)",
                ms(mean_seconds),
                ms(slowest)
            ),
            format!(
                "pictures: contact_sheet.png (every {SHEET_STEP}th frame), trails/{} to trails/{}; \
                 tracks.csv",
                frame_picture_name(0),
                frame_picture_name(last)
            ),
        ]
    }
}
