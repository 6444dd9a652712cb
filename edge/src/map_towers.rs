//! `towernav-edge map-towers`: a survey flight (video or images, a log with
//! GNSS and attitude, the calibration; the same inputs as `replay` and
//! `label`) turned into measured towers. Each frame's pose is the log's GNSS
//! and attitude; the detector's boxes are tracked, each track's views
//! triangulated (`towernav_core::tower_map`), and the towers held against
//! the landmark file where one is given. Writes `towers-mapped.csv` (the
//! landmark import format: confirmed towers under their own id with the
//! measured position, new ones as `NEW-n`), `towers-mapped.geojson` (the
//! same, plus the missed known towers and the towers placed too loosely to
//! propose, each with its status, ellipse and views) and `report.csv`.

use std::path::{Path, PathBuf};

use anyhow::Context;
use geojson::{Feature, FeatureCollection, Geometry, JsonObject, JsonValue};
use towernav_core::survey_labels::{LabelCamera, LabelParams, project_labels};
use towernav_core::tower_map::bearing_misses::BearingMisses;
use towernav_core::tower_map::drift::expected_window_miss;
use towernav_core::tower_map::{
    Anchor, DriftFix, GnssDrift, KnownTower, MappedTower, MatchParams, MatchReport, TowerMapper,
    TowerView, TriangulationParams, Verdict, match_towers,
};
use towernav_core::tracker::{SortParams, SortTracker, Tracker, TrackerInput};
use towernav_flightlog::FlightLog;
use towernav_geometry::Datum;
use towernav_protocol::{LandmarkRecord, TowerType};

use crate::daemon::config::EdgeConfig;
use crate::edge_cmd::load_detector;
use crate::replay::Recording;
use crate::survey::{survey_datum, survey_pose, survey_towers};

/// Options beyond the config's source, log, camera, landmarks and detector.
#[derive(Debug, Clone)]
pub struct MapOptions {
    pub triangulation: TriangulationParams,
    /// A tower placed worse than this (one-sigma, its ellipse's major
    /// semi-axis) is reported as uncertain, not proposed.
    pub max_sigma_m: f64,
    pub matching: MatchParams,
    /// Known towers whose record states a horizontal sigma this small or
    /// smaller anchor the survey (`Anchor`); 0 anchors none.
    pub anchor_sigma_m: f64,
    /// The true towers of a rendered flight, to score the proposals against.
    pub truth: Option<PathBuf>,
    pub out: PathBuf,
}

/// What the mapper found.
#[derive(Debug, Clone)]
pub struct MapRun {
    pub frames: u64,
    /// Frames with no GNSS fix or attitude around them.
    pub without_pose: u64,
    pub tracks: usize,
    pub towers: Vec<MappedTower>,
    /// Towers placed too loosely to propose (few views, one direction).
    pub uncertain: Vec<MappedTower>,
    pub report: MatchReport,
    pub known: Vec<LandmarkRecord>,
    /// Frames where each known tower should have been seen whole.
    pub frames_in_view: Vec<usize>,
    /// The proposals as landmark records, in `towers`' order (`None`: no
    /// height measured, so not importable).
    pub proposals: Vec<Option<LandmarkRecord>>,
    pub datum: Datum,
    pub score: Option<MapScore>,
    /// The looseness past which a tower was reported as uncertain.
    pub max_sigma_m: f64,
}

/// Proposals against the true towers (`--truth`).
#[derive(Debug, Clone, PartialEq)]
pub struct MapScore {
    /// True towers the camera saw whole in at least `SCORE_MIN_VIEWS` frames.
    pub seen: usize,
    /// Of those, how many a proposal lies within `SCORE_MATCH_M` of.
    pub found: usize,
    pub position_rms_m: f64,
    pub position_max_m: f64,
    pub height_rms_m: f64,
    /// Proposals farther than `SCORE_MATCH_M` from every true tower.
    pub phantoms: usize,
    /// Proposals a surveyed record anchored: found, but left out of the
    /// position figures (their place is the record's).
    pub anchored: usize,
    /// The views' bearings against the true towers, with the log's poses.
    pub bearing_misses: Option<BearingMisses>,
}

/// A true tower seen whole in this many frames should be found.
pub const SCORE_MIN_VIEWS: usize = 5;
/// A proposal this close to a true tower is that tower.
pub const SCORE_MATCH_M: f64 = 5.0;

/// Scores the proposals against the true towers; `in_view` counts each true
/// tower's frames seen whole.
fn score<'a>(
    proposals: &[Option<LandmarkRecord>],
    anchored: &[bool],
    truth: &[LandmarkRecord],
    in_view: &[usize],
    views: impl Iterator<Item = &'a TowerView>,
    datum: &Datum,
) -> MapScore {
    let place = |r: &LandmarkRecord| datum.to_enu(&r.foot()).xy();
    let mut found = vec![false; truth.len()];
    let (mut sq, mut max, mut hsq, mut n, mut phantoms) = (0.0, 0.0f64, 0.0, 0, 0);
    let (mut placed, mut held) = (0, 0);
    for (p, &anchor) in proposals.iter().zip(anchored) {
        let Some(p) = p else { continue };
        let nearest = truth
            .iter()
            .enumerate()
            .map(|(k, t)| (k, (place(p) - place(t)).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match nearest {
            Some((k, d)) if d <= SCORE_MATCH_M => {
                found[k] = true;
                if anchor {
                    held += 1;
                } else {
                    sq += d * d;
                    max = max.max(d);
                    placed += 1;
                }
                hsq += (p.height_m - truth[k].height_m).powi(2);
                n += 1;
            }
            _ => phantoms += 1,
        }
    }
    let seen: Vec<usize> = (0..truth.len())
        .filter(|&k| in_view[k] >= SCORE_MIN_VIEWS)
        .collect();
    let rms = |s: f64, n: usize| {
        if n == 0 {
            f64::NAN
        } else {
            (s / n as f64).sqrt()
        }
    };
    MapScore {
        seen: seen.len(),
        found: seen.iter().filter(|&&k| found[k]).count(),
        position_rms_m: rms(sq, placed),
        position_max_m: max,
        height_rms_m: rms(hsq, n),
        phantoms,
        anchored: held,
        bearing_misses: BearingMisses::of(views, &truth.iter().map(place).collect::<Vec<_>>()),
    }
}

/// Maps the towers of the survey flight `config` names into `options.out`.
pub fn map_towers(
    config: &EdgeConfig,
    options: &MapOptions,
    mut progress: impl FnMut(u64, Option<u64>),
) -> anyhow::Result<MapRun> {
    let Recording {
        config,
        mut source,
        log,
        offset_s,
    } = Recording::open(config)?;
    let (width, height) = (config.source.width, config.source.height);
    let datum = survey_datum(&log)?;
    let camera = config.camera.camera(width, height)?;
    let known = match config.landmarks.file.as_deref() {
        Some(path) => towernav_landmark_db::load_towers(path)?,
        None => Vec::new(),
    };
    let survey = survey_towers(&known, &datum)?;
    let truth = match &options.truth {
        Some(path) => towernav_landmark_db::load_towers(path)?,
        None => Vec::new(),
    };
    let truth_survey = survey_towers(&truth, &datum)?;
    let labeller = LabelCamera::new(camera);
    let mut in_view = vec![0usize; known.len()];
    let mut truth_in_view = vec![0usize; truth.len()];
    let mut detector = load_detector(&config.detector)?
        .0
        .context("map-towers needs a detector model (not the oracle)")?;
    let mut tracker = SortTracker::new(SortParams::default());
    let mut mapper = TowerMapper::default().with_drift(log_drift(
        &log,
        &datum,
        offset_s,
        &options.triangulation,
    ));
    let mut run_frames = 0;
    let mut without_pose = 0;
    let total = source.frame_count();
    while let Some(frame) = source.next_frame() {
        let frame = frame?;
        run_frames += 1;
        progress(frame.seq, total);
        let (Some(pose), Some(image)) = (
            survey_pose(&log, &datum, frame.time_s + offset_s),
            frame.image.as_ref(),
        ) else {
            without_pose += 1;
            continue;
        };
        for label in project_labels(&labeller, &pose, &survey, &LabelParams::default()) {
            if label.dropped.is_none() {
                in_view[label.tower] += 1;
            }
        }
        for label in project_labels(&labeller, &pose, &truth_survey, &LabelParams::default()) {
            if label.dropped.is_none() {
                truth_in_view[label.tower] += 1;
            }
        }
        let detections = detector
            .detect(image, frame.seq)
            .with_context(|| format!("the detector on frame {}", frame.seq))?;
        let world_from_camera = camera.world_from_camera(&pose);
        for track in tracker.step(&TrackerInput::new(frame.time_s, &detections)) {
            let b = track.bbox;
            // A box that overlaps another has its centre off the tower's
            // axis: its bearing would pull.
            if detections
                .iter()
                .any(|d| d.bbox != b && d.bbox.intersection_area(&b) > 0.0)
            {
                continue;
            }
            if let Some(view) = TowerView::of_box(&camera, &world_from_camera, &b, frame.time_s) {
                mapper.add(track.track_id, track.tower_type, view);
            }
        }
    }
    // The ground, to find where a tracker swapped two towers: the known
    // towers' feet (without them, tracks are taken whole).
    let ground_z = towernav_core::tower_map::triangulate::median(
        &survey.iter().map(|t| t.foot_in_world.z).collect::<Vec<_>>(),
    );
    let anchors: Vec<Anchor> = known
        .iter()
        .zip(&survey)
        .filter_map(|(r, s)| {
            let sigma_m = r.sigma_horizontal_m.filter(|s| *s > 0.0)?;
            (sigma_m <= options.anchor_sigma_m).then(|| Anchor {
                foot: s.foot_in_world.xy(),
                sigma_m,
            })
        })
        .collect();
    let (towers, uncertain): (Vec<_>, Vec<_>) = mapper
        .finish(&options.triangulation, ground_z, &anchors)
        .into_iter()
        .partition(|t| t.is_solid(options.max_sigma_m));
    let known_in_world: Vec<KnownTower> = known
        .iter()
        .zip(&survey)
        .zip(&in_view)
        .map(|((r, s), &n)| KnownTower {
            id: r.id.clone(),
            foot_in_world: s.foot_in_world,
            height_m: r.height_m,
            sigma_horizontal_m: r.sigma_horizontal_m.filter(|s| *s > 0.0),
            frames_in_view: n,
        })
        .collect();
    let estimates: Vec<_> = towers.iter().map(|t| t.estimate.clone()).collect();
    let report = match_towers(&estimates, &known_in_world, &options.matching);
    let proposals = proposals(&towers, &report, &known, &datum);
    let score = options.truth.is_some().then(|| {
        let anchored: Vec<bool> = towers.iter().map(|t| t.anchored).collect();
        score(
            &proposals,
            &anchored,
            &truth,
            &truth_in_view,
            mapper.views(),
            &datum,
        )
    });
    let run = MapRun {
        frames: run_frames,
        without_pose,
        tracks: mapper.tracks(),
        towers,
        uncertain,
        report,
        known,
        frames_in_view: in_view,
        proposals,
        datum,
        score,
        max_sigma_m: options.max_sigma_m,
    };
    write_outputs(&run, &options.out)?;
    Ok(run)
}

/// The log's fixes that carry a velocity, on the video's clock, as the
/// adjustment's measure of how the GNSS error changes; none where the log
/// has no velocities, or where over 10 s they miss its positions by more
/// than its GNSS error wanders (velocities read or logged wrong).
fn log_drift(log: &FlightLog, datum: &Datum, offset_s: f64, p: &TriangulationParams) -> GnssDrift {
    if p.velocity_sigma_mps <= 0.0 {
        return GnssDrift::default();
    }
    let fixes: Vec<DriftFix> = log
        .gnss
        .iter()
        .filter_map(|g| {
            let v = g.velocity?;
            Some(DriftFix {
                time_s: g.time_s - offset_s,
                position: datum.to_enu(&g.geodetic()?).xy(),
                velocity: nalgebra::Vector2::new(v.east_mps, v.north_mps),
            })
        })
        .collect();
    let drift = GnssDrift::new(&fixes);
    let Some(miss) = drift.window_miss() else {
        tracing::info!(
            "the log gives no GNSS velocities: each second's GNSS error has its prior alone"
        );
        return GnssDrift::default();
    };
    let expected = expected_window_miss(p.position_sigma_m, p.position_correlation_s);
    let (miss_m, expected_m) = (format!("{miss:.2}"), format!("{expected:.2}"));
    if miss > 3.0 * expected + 1.0 {
        tracing::warn!(
            miss_m,
            expected_m,
            "the log's velocities miss its positions over 10 s by more than its GNSS error wanders: left out"
        );
        return GnssDrift::default();
    }
    tracing::info!(
        fixes = fixes.len(),
        miss_m,
        expected_m,
        "the log's GNSS velocities tie each second's GNSS error to the next"
    );
    drift
}

/// Each measured tower as a record to import: a confirmed one keeps its id,
/// line and width; a new one is `NEW-n` with the detector's type.
fn proposals(
    towers: &[MappedTower],
    report: &MatchReport,
    known: &[LandmarkRecord],
    datum: &Datum,
) -> Vec<Option<LandmarkRecord>> {
    let mut new = 0;
    towers
        .iter()
        .zip(&report.verdicts)
        .map(|(t, v)| {
            let e = &t.estimate;
            let height = e.height_m?;
            let foot = datum.to_geodetic(&e.foot_in_world);
            let mut r = match v {
                Verdict::Confirms {
                    known: k,
                    offset_en,
                    height_difference_m,
                } => {
                    let mut r = known[*k].clone();
                    r.notes = format!(
                        "confirms {}: {:.1} m off (east {:+.1}, north {:+.1}), height {}",
                        r.id,
                        offset_en.norm(),
                        offset_en.x,
                        offset_en.y,
                        height_difference_m.map_or("not measured".into(), |d| format!("{d:+.1} m"))
                    );
                    r
                }
                Verdict::New => {
                    new += 1;
                    let mut r = LandmarkRecord::new(
                        format!("NEW-{new}"),
                        t.tower_type.unwrap_or(TowerType::A),
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                    );
                    r.notes = "not in the landmark file".into();
                    r
                }
            };
            // An anchored tower's place is its record's: the survey's, which
            // the flight was held to, not a measurement of its own.
            if t.anchored {
                r.notes = format!("{}; the surveyed place anchored the flight", r.notes);
            } else {
                r.lat_deg = foot.lat_deg;
                r.lon_deg = foot.lon_deg;
                r.ground_elev_m = foot.height_m;
                r.sigma_horizontal_m = Some(e.sigma_horizontal_m());
            }
            r.height_m = height;
            r.survey_source = Some("towernav-edge map-towers".into());
            r.sigma_vertical_m = Some(e.height_sigma_m);
            r.notes = format!(
                "{}; {} views, {} with height",
                r.notes, e.views, e.height_views
            );
            r.updated_at_unix_s = 0;
            r.updated_by = String::new();
            r.revision = 0;
            Some(r)
        })
        .collect()
}

/// The ellipse of a 2x2 covariance: one-sigma semi-axes (major, minor), m,
/// and the major axis's bearing, degrees clockwise from north.
pub fn ellipse(cov: &nalgebra::Matrix2<f64>) -> (f64, f64, f64) {
    let eig = cov.symmetric_eigen();
    let (i, j) = if eig.eigenvalues[0] >= eig.eigenvalues[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    let axis = eig.eigenvectors.column(i);
    let bearing = axis[0].atan2(axis[1]).to_degrees().rem_euclid(180.0);
    (
        eig.eigenvalues[i].max(0.0).sqrt(),
        eig.eigenvalues[j].max(0.0).sqrt(),
        bearing,
    )
}

fn feature(r: &LandmarkRecord, status: &str, extra: JsonObject) -> Feature {
    let mut properties = match serde_json::to_value(r) {
        Ok(JsonValue::Object(map)) => map,
        _ => JsonObject::new(),
    };
    properties.remove("lat_deg");
    properties.remove("lon_deg");
    properties.retain(|_, v| !v.is_null());
    properties.insert("status".into(), status.into());
    properties.extend(extra);
    Feature {
        bbox: None,
        geometry: Some(Geometry::new(geojson::GeometryValue::Point {
            coordinates: vec![r.lon_deg, r.lat_deg, r.ground_elev_m].into(),
        })),
        id: Some(geojson::feature::Id::String(r.id.clone())),
        properties: Some(properties),
        foreign_members: None,
    }
}

fn write_outputs(run: &MapRun, out: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let importable: Vec<LandmarkRecord> = run.proposals.iter().flatten().cloned().collect();
    let csv_path = out.join("towers-mapped.csv");
    let file = std::fs::File::create(&csv_path)
        .with_context(|| format!("creating {}", csv_path.display()))?;
    towernav_landmark_db::export_csv(&importable, file)
        .with_context(|| format!("writing {}", csv_path.display()))?;

    let mut features = Vec::new();
    let mut report = String::from(
        "status,id,known_id,lat_deg,lon_deg,ground_elev_m,height_m,sigma_major_m,sigma_minor_m,\
         ellipse_bearing_deg,height_sigma_m,views,height_views,offset_east_m,offset_north_m,\
         height_difference_m,frames_in_view\n",
    );
    for ((t, v), proposal) in run
        .towers
        .iter()
        .zip(&run.report.verdicts)
        .zip(&run.proposals)
    {
        let e = &t.estimate;
        let (major, minor, bearing) = ellipse(&e.covariance_en);
        let foot = run.datum.to_geodetic(&e.foot_in_world);
        let (status, known_id, offset, dh) = match v {
            Verdict::Confirms {
                known,
                offset_en,
                height_difference_m,
            } => (
                "confirmed",
                run.known[*known].id.clone(),
                Some(*offset_en),
                *height_difference_m,
            ),
            Verdict::New => ("new", String::new(), None, None),
        };
        let record = proposal.clone().unwrap_or_else(|| {
            let mut r = LandmarkRecord::new(
                format!("UNMEASURED-{}", t.track_ids[0]),
                t.tower_type.unwrap_or(TowerType::A),
                foot.lat_deg,
                foot.lon_deg,
                foot.height_m,
                0.0,
            );
            r.notes = "no view saw it whole: no height".into();
            r
        });
        let mut extra = JsonObject::new();
        extra.insert("sigma_major_m".into(), major.into());
        extra.insert("sigma_minor_m".into(), minor.into());
        extra.insert("ellipse_bearing_deg".into(), bearing.into());
        extra.insert("views".into(), e.views.into());
        extra.insert("height_views".into(), e.height_views.into());
        extra.insert("anchored".into(), t.anchored.into());
        if let Some(o) = offset {
            extra.insert("known_id".into(), known_id.clone().into());
            extra.insert("offset_east_m".into(), o.x.into());
            extra.insert("offset_north_m".into(), o.y.into());
        }
        if let Some(d) = dh {
            extra.insert("height_difference_m".into(), d.into());
        }
        features.push(feature(&record, status, extra));
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.2}"));
        report.push_str(&format!(
            "{status},{},{known_id},{:.7},{:.7},{:.2},{},{major:.2},{minor:.2},{bearing:.0},{:.2},{},{},{},{},{},\n",
            record.id,
            foot.lat_deg,
            foot.lon_deg,
            foot.height_m,
            opt(e.height_m),
            e.height_sigma_m,
            e.views,
            e.height_views,
            opt(offset.map(|o| o.x)),
            opt(offset.map(|o| o.y)),
            opt(dh),
        ));
    }
    for t in &run.uncertain {
        let e = &t.estimate;
        let (major, minor, bearing) = ellipse(&e.covariance_en);
        let foot = run.datum.to_geodetic(&e.foot_in_world);
        let mut r = LandmarkRecord::new(
            format!("UNCERTAIN-{}", t.track_ids[0]),
            t.tower_type.unwrap_or(TowerType::A),
            foot.lat_deg,
            foot.lon_deg,
            foot.height_m,
            e.height_m.unwrap_or(0.0),
        );
        r.notes = t.doubt(run.max_sigma_m).unwrap_or_default();
        let mut extra = JsonObject::new();
        extra.insert("followed_s".into(), t.followed_s.into());
        extra.insert("sigma_major_m".into(), major.into());
        extra.insert("sigma_minor_m".into(), minor.into());
        extra.insert("ellipse_bearing_deg".into(), bearing.into());
        extra.insert("views".into(), e.views.into());
        features.push(feature(&r, "uncertain", extra));
        report.push_str(&format!(
            "uncertain,{},,{:.7},{:.7},{:.2},{},{major:.2},{minor:.2},{bearing:.0},{:.2},{},{},,,,\n",
            r.id,
            foot.lat_deg,
            foot.lon_deg,
            foot.height_m,
            e.height_m.map_or(String::new(), |h| format!("{h:.2}")),
            e.height_sigma_m,
            e.views,
            e.height_views,
        ));
    }
    for &k in &run.report.missed {
        let r = &run.known[k];
        let mut extra = JsonObject::new();
        extra.insert("frames_in_view".into(), run.frames_in_view[k].into());
        features.push(feature(r, "missed", extra));
        report.push_str(&format!(
            "missed,{},{},{:.7},{:.7},{:.2},{:.2},,,,,,,,,,{}\n",
            r.id, r.id, r.lat_deg, r.lon_deg, r.ground_elev_m, r.height_m, run.frames_in_view[k]
        ));
    }
    let geojson_path = out.join("towers-mapped.geojson");
    let text = serde_json::to_string_pretty(&FeatureCollection {
        bbox: None,
        features,
        foreign_members: None,
    })?;
    std::fs::write(&geojson_path, text)
        .with_context(|| format!("writing {}", geojson_path.display()))?;
    let report_path = out.join("report.csv");
    std::fs::write(&report_path, report)
        .with_context(|| format!("writing {}", report_path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix2, Point3, Vector2};
    use towernav_core::tower_map::TowerEstimate;
    use towernav_geometry::Geodetic;

    use super::*;

    fn mapped(foot: Point3<f64>, anchored: bool) -> MappedTower {
        MappedTower {
            estimate: TowerEstimate {
                foot_in_world: foot,
                covariance_en: Matrix2::identity() * 0.25,
                height_m: Some(41.0),
                height_sigma_m: 0.4,
                views: 300,
                height_views: 250,
                spread_rad: 0.3,
                inlier_share: 1.0,
            },
            tower_type: Some(TowerType::B),
            track_ids: vec![1],
            followed_s: 20.0,
            anchored,
        }
    }

    #[test]
    fn an_anchored_tower_keeps_its_surveyed_place_and_is_not_scored_as_measured() {
        let datum = Datum::new(Geodetic::new(30.52, 114.36, 25.0).expect("valid"));
        let at = |e: f64, n: f64| datum.to_geodetic(&Point3::new(e, n, 0.0));
        let record = |id: &str, e: f64, n: f64, sigma: Option<f64>| {
            let g = at(e, n);
            let mut r =
                LandmarkRecord::new(id, TowerType::B, g.lat_deg, g.lon_deg, g.height_m, 40.0);
            r.sigma_horizontal_m = sigma;
            r
        };
        // B1 surveyed to 10 cm, the flight 3 cm from it; B2 from a map.
        let known = vec![
            record("B1", 0.0, 0.0, Some(0.1)),
            record("B2", 200.0, 0.0, None),
        ];
        let towers = vec![
            mapped(Point3::new(0.03, 0.0, 0.0), true),
            mapped(Point3::new(203.0, 1.0, 0.0), false),
        ];
        let confirms = |known, offset_en| Verdict::Confirms {
            known,
            offset_en,
            height_difference_m: Some(1.0),
        };
        let report = MatchReport {
            verdicts: vec![
                confirms(0, Vector2::new(0.03, 0.0)),
                confirms(1, Vector2::new(3.0, 1.0)),
            ],
            missed: vec![],
            not_seen: vec![],
        };
        let proposals = proposals(&towers, &report, &known, &datum);
        let b1 = proposals[0].as_ref().expect("B1 proposed");
        assert_eq!(
            (b1.lat_deg, b1.lon_deg, b1.sigma_horizontal_m),
            (known[0].lat_deg, known[0].lon_deg, Some(0.1))
        );
        assert_eq!(b1.height_m, 41.0, "the height is still the flight's");
        let b2 = proposals[1].as_ref().expect("B2 proposed");
        assert!(
            (b2.lon_deg - known[1].lon_deg).abs() > 1e-5,
            "B2 moves to where it was measured"
        );

        // Against the truth (where the records are), B1 is found but only
        // B2's 3.2 m is a measured place.
        let truth = known.clone();
        let s = score(
            &proposals,
            &[true, false],
            &truth,
            &[50, 50],
            std::iter::empty(),
            &datum,
        );
        assert_eq!((s.found, s.anchored), (2, 1));
        assert!((s.position_rms_m - 10f64.sqrt()).abs() < 0.05, "{s:?}");
    }
}
