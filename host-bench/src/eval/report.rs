//! Reporting: the human summary, the CSV log and the SVG plot of a run.
//!
//! Files are written atomically ([`write_atomically`]), so an interrupted or failed run never
//! leaves a half-written file behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::formats::atomic::Staged;
use crate::sim::emulator::{self, LogRow, Run, Scenario, Summary};

/// The short summary `emulate` prints.
pub fn summary_text(s: &Summary) -> String {
    let ok = |b: bool| if b { "ok" } else { "MISMATCH" };
    let tracking = match (s.tracking_rms_m, s.tracking_max_m) {
        (Some(rms), Some(max)) => format!(
            "tracking        tracked point vs the path: RMS {:.2} mm, max {:.2} mm (from 1 s on, {} physics steps)\n",
            rms * 1e3,
            max * 1e3,
            s.tracking_samples
        ),
        _ => String::new(),
    };
    let text = format!(
        "scenario        {scenario} (seed {seed}), robot {robot}{uploaded}{truly}, slave odometry `{algorithm}`\n\
         simulated       {sim:.3} s in {wall:.3} s wall ({speed:.0}x real time)\n\
         path length     {path:.3} m\n\
         slave odometry  final error {fe:.2} mm, max {me:.2} mm, final heading error {he:.3} deg\n\
         encoders        {p0:.3} and {p1:.3} of a count past an edge at power-on, edges {edges}\n\
         robot           ended at ({x:.4}, {y:.4}) m, {dg:.1} mm from the goal{arr}\n\
         motors          switched on {on} times{after}\n\
         SPI frames      {spi} exchanged, {spir} rejected{inj}{view}\n\
         serial frames   {ser} exchanged, {serr} rejected (protocol v{pv}, schema {fp})\n",
        scenario = s.scenario,
        robot = s.robot,
        uploaded = s.robot_uploaded.map_or(String::new(), |fp| format!(
            " (encoders uploaded to the slave, fingerprint {fp:08x})"
        )),
        truly = s.true_robot.as_ref().map_or(String::new(), |t| format!(
            "; the simulated robot is really {t}"
        )),
        algorithm = s.algorithm,
        seed = s.seed,
        sim = s.sim_seconds,
        wall = s.wall_seconds,
        speed = s.speed_x,
        path = s.path_length_m,
        fe = s.final_error_m * 1e3,
        me = s.max_error_m * 1e3,
        he = s.final_heading_error_rad.to_degrees(),
        p0 = s.encoder_phase[0],
        p1 = s.encoder_phase[1],
        edges = s.encoder_edges,
        x = s.final_position_m.0,
        y = s.final_position_m.1,
        dg = s.distance_to_goal_m * 1e3,
        arr = if s.arrived { " (arrived)" } else { "" },
        on = s.motor_switch_ons,
        after = match (
            s.motor_switch_ons_after_arrival,
            s.motor_driven_s_after_arrival
        ) {
            (Some(n), Some(t)) => format!(", {n} after arriving (driven {t:.2} s after it)"),
            _ => String::new(),
        },
        spi = s.spi_frames,
        spir = s.spi_frames_rejected,
        inj = {
            let i = &s.spi_injected;
            if i.corrupted_to_master
                + i.corrupted_to_slave
                + i.dropped
                + i.torn
                + i.duplicated
                + i.late
                > 0
            {
                let mut torn = if i.torn > 0 {
                    format!(", {} torn", i.torn)
                } else {
                    String::new()
                };
                if i.duplicated > 0 {
                    torn += &format!(", {} sent twice by a slave late to re-arm", i.duplicated);
                }
                if i.late > 0 {
                    torn += &format!(", {} with chip select released late", i.late);
                }
                let (m, sl) = (&s.spi_rejected_kinds_master, &s.spi_rejected_kinds_slave);
                let rep = if m.repeated > 0 {
                    format!(", {} repeated (to the master)", m.repeated)
                } else {
                    String::new()
                };
                format!(
                    " ({} by the master, {} by the slave; injected: {} corrupted to the master, \
                     {} to the slave, {} transactions lost{torn}; by why: {} and {} bad checks, \
                     {} and {} of the wrong kind, {} and {} undecodable, {} and {} non-canonical{rep})",
                    s.spi_rejected_by_master,
                    s.spi_rejected_by_slave,
                    i.corrupted_to_master,
                    i.corrupted_to_slave,
                    i.dropped,
                    m.crc,
                    sl.crc,
                    m.kind,
                    sl.kind,
                    m.decode,
                    sl.decode,
                    m.non_canonical,
                    sl.non_canonical
                )
            } else {
                String::new()
            }
        },
        view = match s.master_view_matches_slave {
            Some(true) => "; standing at the goal, the master's last view of the slave's pose is the slave's own",
            Some(false) => "; standing at the goal, the master's last view of the slave's pose DIFFERS from the slave's",
            None => "",
        },
        ser = s.serial_frames,
        serr = s.serial_frames_rejected,
        pv = s.protocol_version,
        fp = ok(s.schema_fingerprint_match),
    );
    let faults = match &s.fault_check {
        Some(c) => format!(
            "vs clean run    closed loop: the slave's pose ends {:.3} mm from the clean run's (the master steered on older frames while the faults held new ones back); driven through the clean run's duties with the same faults: {}, the master's view {}\n",
            c.closed_loop_apart_m * 1e3,
            if c.same_motion_equals_clean {
                "the slave's pose equals the clean run's bit for bit"
            } else {
                "the slave's pose DIFFERS from the clean run's"
            },
            match c.same_motion_master_view_matches_slave {
                Some(true) => "the slave's own",
                Some(false) => "DIFFERS from the slave's",
                None => "not checked (the robot never stood at its goal)",
            }
        ),
        None => String::new(),
    };
    let reset = match &s.slave_reset {
        Some(r) => {
            let after = |t: Option<f64>| {
                t.map_or("NEVER".to_string(), |t| {
                    format!("{:.1} ms after", (t - r.at_s) * 1e3)
                })
            };
            format!(
                "slave reset     at {:.3} s: the master told {}, stopped the motors {}, the host read it {} (the slave's pose since is its power-on pose: the max error above is up to the reset)\n",
                r.at_s,
                after(s.slave_reset_told_s),
                after(r.motors_stopped_s),
                after(r.host_told_s),
            )
        }
        None => match s.slave_reset_told_s {
            Some(t) => format!(
                "slave reset     the master reported one at {t:.3} s, but none was injected\n"
            ),
            None => String::new(),
        },
    };
    text + &tracking + &faults + &reset
}

/// Most log rows drawn in `path.svg`: the plot thins a longer log evenly, so a long run's plot
/// stays a few MB and its memory flat.
pub const MAX_PLOTTED_ROWS: usize = 10_000;

/// Most rows in `run.csv` (about 190 MB): every log row of a run up to 2.8 simulated hours,
/// every k-th of a longer one, so a week's run writes as much as 2.8 hours' (it wrote 11 GB).
pub const MAX_CSV_ROWS: u64 = 1_000_000;

/// An `emulate --out` run's files, written under temporary names, none yet in place.
/// [`commit`](Self::commit) puts them all in place; dropped (the run scored nothing, the fault
/// check failed, Ctrl-C), none is, no existing one is replaced, and a folder it made goes.
pub struct EmulateFiles {
    // Dropped in this order: the temporary files first, then the folder (if it is empty).
    staged: Staged,
    paths: Vec<PathBuf>,
    json_path: PathBuf,
    dir: crate::formats::atomic::OutputDir,
}

impl EmulateFiles {
    /// Writes `summary.json` from `summary` (the run's, with what was added since: the fault
    /// check) and puts the three files in place.
    pub fn commit(mut self, summary: &emulator::Summary) -> Result<Vec<PathBuf>> {
        self.staged.write(&self.json_path, |file| {
            serde_json::to_writer_pretty(&mut *file, summary)?;
            Ok(file.write_all(b"\n")?)
        })?;
        self.staged.commit()?;
        self.dir.keep();
        self.paths.push(self.json_path);
        Ok(self.paths)
    }
}

/// Runs `scenario` writing `run.csv` and `path.svg` for `--out dir` (staged: see
/// [`EmulateFiles`]). Every output is checked before the run starts. `also` sees every log
/// row as it is made (the MCAP file, the live view).
pub fn emulate_into(
    scenario: &Scenario,
    opts: &emulator::Options,
    dir: &Path,
    also: &mut dyn FnMut(&emulator::LogRow) -> Result<()>,
) -> Result<(Run, EmulateFiles)> {
    emulator::check_options(opts)?;
    if dir.exists() && !dir.is_dir() {
        anyhow::bail!("--out {}: exists and is not a directory", dir.display());
    }
    // Made with its parents, and gone again (if empty) should the run fail or be stopped.
    let out = crate::formats::atomic::OutputDir::create(dir)
        .with_context(|| format!("--out {}", dir.display()))?;
    let (csv_path, svg_path, json_path) = (
        dir.join("run.csv"),
        dir.join("path.svg"),
        dir.join("summary.json"),
    );
    let png_path = crate::eval::png::beside(&svg_path);
    let inputs: Vec<(&str, &Path)> = (scenario.source_files.iter())
        .map(|(w, p)| (*w, p.as_path()))
        .collect();
    crate::formats::atomic::refuse_inputs(
        &format!("--out {}", dir.display()),
        &[
            csv_path.clone(),
            svg_path.clone(),
            png_path.clone(),
            json_path.clone(),
        ],
        &inputs,
    )?;
    for p in [&csv_path, &svg_path, &png_path, &json_path] {
        crate::formats::atomic::check_output(p)
            .with_context(|| format!("--out {}", dir.display()))?;
    }
    let mut staged = Staged::default();
    let run = stage_run_csv(scenario, opts, &csv_path, &mut staged, also)?;
    let mut text = String::new();
    draw_run(
        &run,
        SVGBackend::with_string(&mut text, (800, 1100)).into_drawing_area(),
    )?;
    crate::eval::png::stage(&mut staged, &svg_path, &text)?;
    Ok((
        run,
        EmulateFiles {
            staged,
            paths: vec![csv_path, svg_path, png_path],
            json_path,
            dir: out,
        },
    ))
}

/// The run, its log streamed into `csv_path` (staged in `staged`).
fn stage_run_csv(
    scenario: &Scenario,
    opts: &emulator::Options,
    csv_path: &Path,
    staged: &mut Staged,
    also: &mut dyn FnMut(&emulator::LogRow) -> Result<()>,
) -> Result<Run> {
    let mut plotted = Thinned::new(MAX_PLOTTED_ROWS);
    let rows = (opts.duration / opts.log_period).ceil().max(1.0);
    let every = (rows / MAX_CSV_ROWS as f64).ceil().max(1.0) as u64;
    let mut row_index = 0u64;
    // The run's own failure (a session the master refused, ...) is reported as itself, not as
    // a file that could not be written.
    let mut run_failed = None;
    let mut summary = None;
    let written = staged.write(csv_path, |file| {
        let mut w = csv::Writer::from_writer(std::io::BufWriter::new(file));
        let mut write_failed = false;
        let run = emulator::run_logged(
            scenario,
            opts,
            Some(&mut |row| {
                also(&row)?;
                if row_index.is_multiple_of(every) {
                    let written = w.serialize(&row);
                    write_failed = written.is_err();
                    written?;
                }
                row_index += 1;
                plotted.push(row);
                Ok(())
            }),
        );
        match run {
            Ok(s) => summary = Some(s),
            Err(e) if write_failed => return Err(e),
            Err(e) => {
                let why = format!("{e:#}");
                run_failed = Some(e);
                anyhow::bail!("{why}");
            }
        };
        w.flush()?;
        Ok(())
    });
    match (written, run_failed, summary) {
        (Ok(()), _, Some(summary)) => Ok(Run {
            summary,
            log: plotted.rows,
        }),
        (Err(_), Some(run_error), _) => Err(run_error),
        (Err(e), None, _) => Err(e),
        (Ok(()), _, None) => anyhow::bail!("the run ended without a summary"),
    }
}

/// Every `stride`-th row of a stream, the stride doubling whenever `2 × cap` rows are kept:
/// evenly spaced, between `cap` and `2 × cap` of them, whatever the stream's length.
struct Thinned<T> {
    rows: Vec<T>,
    cap: usize,
    stride: usize,
    seen: usize,
}

impl<T> Thinned<T> {
    fn new(cap: usize) -> Self {
        Thinned {
            rows: Vec::new(),
            cap: cap.max(1),
            stride: 1,
            seen: 0,
        }
    }

    fn push(&mut self, row: T) {
        if self.seen.is_multiple_of(self.stride) {
            self.rows.push(row);
        }
        self.seen += 1;
        if self.rows.len() >= 2 * self.cap {
            let mut k = 0;
            self.rows.retain(|_| {
                k += 1;
                (k - 1) % 2 == 0
            });
            self.stride *= 2;
        }
    }
}

/// An 800 x 1100 SVG drawn by `draw`, as text.
fn svg(draw: impl FnOnce(DrawingArea<SVGBackend<'_>, Shift>) -> Result<()>) -> Result<String> {
    let mut text = String::new();
    draw(SVGBackend::with_string(&mut text, (800, 1100)).into_drawing_area())?;
    Ok(text)
}

/// The run's plot: the paths on top, the position error against time below.
fn draw_run(run: &Run, root: DrawingArea<SVGBackend<'_>, Shift>) -> Result<()> {
    let log = &run.log;
    let pts = |f: fn(&LogRow) -> Option<(f64, f64)>| -> Vec<(f64, f64)> {
        log.iter().filter_map(f).collect()
    };
    let truth = pts(|r| Some((r.true_x_m, r.true_y_m)));
    let slave = pts(|r| Some((r.slave_x_m, r.slave_y_m)));
    let master = pts(|r| r.master_x_m.zip(r.master_y_m));
    let target = pts(|r| r.target_x_m.zip(r.target_y_m));

    let (x0, x1, y0, y1) = square_bounds(truth.iter().chain(&slave).chain(&target));

    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(860);
    let s = &run.summary;
    let caption = format!(
        "{}: slave odometry error final {:.2} mm, max {:.2} mm",
        s.scenario,
        s.final_error_m * 1e3,
        s.max_error_m * 1e3
    );
    let mut chart = ChartBuilder::on(&top)
        .caption(caption, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()?;
    // The truth wide and pale underneath, the estimates thin over it: an estimate within a
    // millimetre of the truth shows as a line inside the wide one, not hidden under it.
    chart
        .draw_series(LineSeries::new(
            truth.iter().copied(),
            RGBColor(0, 0, 0).mix(0.25).stroke_width(9),
        ))?
        .label("ground truth (wide)")
        .legend(|(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], BLACK.mix(0.25).stroke_width(6))
        });
    for (name, data, color) in [
        ("target", &target, RGBColor(150, 150, 150)),
        ("slave odometry", &slave, SLAVE_COLOR),
    ] {
        chart
            .draw_series(LineSeries::new(data.iter().copied(), color.stroke_width(1)))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    // Dashed, so the slave's line shows through the master's where they coincide.
    chart
        .draw_series(DashedLineSeries::new(
            master.iter().copied(),
            6,
            4,
            MASTER_COLOR.stroke_width(1),
        ))?
        .label("master estimate (dashed)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], MASTER_COLOR.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::LowerRight)
        .draw()?;
    draw_error_panel(&bottom, log)?;
    root.present()?;
    Ok(())
}

const SLAVE_COLOR: RGBColor = RGBColor(220, 40, 40);
const MASTER_COLOR: RGBColor = RGBColor(40, 90, 220);

/// Position error against ground truth over time, in millimetres: at the paths' scale the
/// estimates sit on the truth, so the error needs its own axis to be seen at all. A log axis:
/// a start transient of centimetres (the master's estimate before the host sets the pose)
/// would otherwise flatten a run's hundredths of a millimetre onto zero.
fn draw_error_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    log: &[LogRow],
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    // 0.1 µm: an error below reads as the floor.
    let floor = 1e-4;
    let err = |x: Option<f64>, y: Option<f64>, r: &LogRow| -> Option<(f64, f64)> {
        Some((
            r.t_s,
            ((x? - r.true_x_m).hypot(y? - r.true_y_m) * 1e3).max(floor),
        ))
    };
    let slave: Vec<_> = log
        .iter()
        .filter_map(|r| err(Some(r.slave_x_m), Some(r.slave_y_m), r))
        .collect();
    let master: Vec<_> = log
        .iter()
        .filter_map(|r| err(r.master_x_m, r.master_y_m, r))
        .collect();
    let t_end = log.last().map_or(1.0, |r| r.t_s).max(1e-3);
    let e_max = slave
        .iter()
        .chain(&master)
        .map(|p| p.1)
        .fold(1e-2f64, f64::max)
        * 3.0;
    let mut chart = ChartBuilder::on(area)
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, (floor..e_max).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("position error (mm, log)")
        .draw()?;
    let series: [Series; 2] = [
        ("slave odometry", &slave, SLAVE_COLOR),
        ("master estimate", &master, MASTER_COLOR),
    ];
    draw_lines(&mut chart, &series, 1, SeriesLabelPosition::UpperRight)
}

/// A square window (x0, x1, y0, y1) around the points with a 10 % margin: equal scales on both
/// axes, so a path's shape is true.
fn square_bounds<'a>(points: impl IntoIterator<Item = &'a (f64, f64)>) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (-1.0, 1.0, -1.0, 1.0);
    }
    let span = (x1 - x0).max(y1 - y0).max(0.1) * 1.1;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    (
        cx - span / 2.0,
        cx + span / 2.0,
        cy - span / 2.0,
        cy + span / 2.0,
    )
}

/// A named line in a plot: legend label, points, colour.
type Series<'a> = (&'a str, &'a [(f64, f64)], RGBColor);

/// [`Series`] that owns its label and points.
type OwnedSeries = (String, Vec<(f64, f64)>, RGBColor);

/// Draw named line series with a legend; empty series are left out.
fn draw_lines<'a, DB: DrawingBackend + 'a, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'a, DB, CT>,
    series: &[Series],
    width: u32,
    legend_at: SeriesLabelPosition,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    for &(name, data, color) in series {
        if data.is_empty() {
            continue;
        }
        chart
            .draw_series(LineSeries::new(
                data.iter().copied(),
                color.stroke_width(width),
            ))?
            .label(name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(legend_at)
        .draw()?;
    Ok(())
}

/// One picture for an accuracy case: the true path and each method's path on top, and each
/// method's position error against distance travelled below (log scale: the methods differ
/// by orders of magnitude). As SVG text, for files written together (`atomic::Staged`).
pub fn case_svg(title: &str, scores: &[crate::eval::replay::Score]) -> Result<String> {
    svg(|root| draw_case(root, title, scores))
}

const METHOD_COLORS: [RGBColor; 4] = [
    RGBColor(230, 140, 20),
    RGBColor(40, 160, 60),
    RGBColor(150, 60, 200),
    RGBColor(220, 40, 40),
];

fn draw_case(
    root: DrawingArea<SVGBackend<'_>, Shift>,
    title: &str,
    scores: &[crate::eval::replay::Score],
) -> Result<()> {
    let Some(first) = scores.first() else {
        anyhow::bail!("no method ran on {title}");
    };
    let truth: Vec<(f64, f64)> = first.track.iter().map(|(_, _, t)| (t.x, t.y)).collect();
    let (x0, x1, y0, y1) = square_bounds(&truth);
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(800);
    let mut chart = ChartBuilder::on(&top)
        .caption(title, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()?;
    let paths: Vec<OwnedSeries> =
        std::iter::once(("ground truth".to_string(), truth.clone(), BLACK))
            .chain(
                scores
                    .iter()
                    .zip(METHOD_COLORS.iter().cycle())
                    .map(|(s, &c)| {
                        (
                            s.name.clone(),
                            s.track.iter().map(|(_, e, _)| (e.x, e.y)).collect(),
                            c,
                        )
                    }),
            )
            .collect();
    let series: Vec<Series> = paths
        .iter()
        .map(|(n, p, c)| (n.as_str(), p.as_slice(), *c))
        .collect();
    draw_lines(&mut chart, &series, 1, SeriesLabelPosition::LowerRight)?;

    // Error against distance travelled along the truth, log scale.
    let mut travelled = Vec::with_capacity(truth.len());
    let mut d = 0.0;
    for (i, p) in truth.iter().enumerate() {
        if i > 0 {
            d += (p.0 - truth[i - 1].0).hypot(p.1 - truth[i - 1].1);
        }
        travelled.push(d);
    }
    let floor = 1e-4; // µm; errors below read as the floor
    let errors: Vec<OwnedSeries> = scores
        .iter()
        .zip(METHOD_COLORS.iter().cycle())
        .map(|(s, &c)| {
            let e = s
                .track
                .iter()
                .zip(&travelled)
                .map(|((_, e, t), &d)| (d, (e.distance_to(*t) * 1e6).max(floor)))
                .collect();
            (s.name.clone(), e, c)
        })
        .collect();
    let e_max = errors
        .iter()
        .flat_map(|(_, e, _)| e.iter().map(|p| p.1))
        .fold(1.0f64, f64::max)
        * 2.0;
    let mut chart = ChartBuilder::on(&bottom)
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..d.max(1e-3), (floor..e_max).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("distance travelled (m)")
        .y_desc("position error (µm)")
        .draw()?;
    let series: Vec<Series> = errors
        .iter()
        .map(|(n, p, c)| (n.as_str(), p.as_slice(), *c))
        .collect();
    draw_lines(&mut chart, &series, 1, SeriesLabelPosition::LowerRight)?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Thinned;

    #[test]
    fn thinning_keeps_evenly_spaced_rows_between_cap_and_twice_cap() {
        for n in [0usize, 1, 7, 8, 15, 16, 17, 100, 1000, 12_345] {
            let mut t = Thinned::new(8);
            for i in 0..n {
                t.push(i);
            }
            let kept = &t.rows;
            assert!(kept.len() < 16, "n {n}: kept {}", kept.len());
            assert!(kept.len() >= n.min(8), "n {n}: kept {}", kept.len());
            assert_eq!(kept.first().copied(), (n > 0).then_some(0));
            assert!(
                kept.windows(2).all(|w| w[1] - w[0] == t.stride),
                "n {n}: {kept:?} not every {}",
                t.stride
            );
        }
    }
}
