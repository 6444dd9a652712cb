//! What a surveyed tower must satisfy before it is stored or used for a fix.

use towernav_protocol::LandmarkRecord;

/// A record field that is wrong, named so a surveyor can find and fix it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("landmark {id:?}: {field} {reason}")]
pub struct ValidationError {
    pub id: String,
    pub field: &'static str,
    pub reason: String,
}

/// Tallest tower the database accepts; taller is almost surely a unit slip (feet, cm).
pub const MAX_HEIGHT_M: f64 = 200.0;

pub fn validate(r: &LandmarkRecord) -> Result<(), ValidationError> {
    let err = |field, reason: String| {
        Err(ValidationError {
            id: r.id.clone(),
            field,
            reason,
        })
    };
    if r.id.trim().is_empty() {
        return err("id", "is empty".into());
    }
    if r.id.len() > 32
        || !r
            .id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c))
    {
        return err("id", "must be 1-32 of A-Z a-z 0-9 _ - .".into());
    }
    if !(r.lat_deg.is_finite() && (-90.0..=90.0).contains(&r.lat_deg)) {
        return err(
            "lat_deg",
            format!("{} is not between -90 and 90", r.lat_deg),
        );
    }
    if !(r.lon_deg.is_finite() && (-180.0..=180.0).contains(&r.lon_deg)) {
        return err(
            "lon_deg",
            format!("{} is not between -180 and 180", r.lon_deg),
        );
    }
    if !(r.ground_elev_m.is_finite() && (-500.0..=9000.0).contains(&r.ground_elev_m)) {
        return err(
            "ground_elev_m",
            format!("{} m is not between -500 and 9000 m", r.ground_elev_m),
        );
    }
    if !(r.height_m.is_finite() && r.height_m > 0.0 && r.height_m <= MAX_HEIGHT_M) {
        return err(
            "height_m",
            format!("{} m is not between 0 and {MAX_HEIGHT_M} m", r.height_m),
        );
    }
    let optional = [
        ("base_width_m", r.base_width_m, 50.0),
        ("sigma_horizontal_m", r.sigma_horizontal_m, 100.0),
        ("sigma_vertical_m", r.sigma_vertical_m, 100.0),
    ];
    for (field, value, max) in optional {
        if let Some(v) = value
            && !(v.is_finite() && (0.0..=max).contains(&v))
        {
            return err(field, format!("{v} m is not between 0 and {max} m"));
        }
    }
    let text = [
        ("line_name", r.line_name.as_deref().unwrap_or_default()),
        (
            "survey_source",
            r.survey_source.as_deref().unwrap_or_default(),
        ),
        ("notes", r.notes.as_str()),
        ("updated_by", r.updated_by.as_str()),
    ];
    for (field, value) in text {
        if let Some(c) = value
            .chars()
            .find(|c| c.is_control() && !matches!(c, '\t' | '\n' | '\r'))
        {
            return err(
                field,
                format!(
                    "holds the control character U+{:04X}; remove it",
                    u32::from(c)
                ),
            );
        }
    }
    if r.base_width_m == Some(0.0) {
        return err("base_width_m", "is zero; leave it empty if unknown".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_protocol::TowerType;

    fn good() -> LandmarkRecord {
        LandmarkRecord {
            base_width_m: Some(7.0),
            sigma_horizontal_m: Some(0.05),
            ..LandmarkRecord::new("A1", TowerType::A, 30.5, 114.3, 20.0, 35.0)
        }
    }

    #[test]
    fn a_good_record_passes() {
        assert_eq!(validate(&good()), Ok(()));
    }

    #[test]
    fn each_bad_field_is_named() {
        type Spoil = fn(&mut LandmarkRecord);
        let cases: [(&str, Spoil); 9] = [
            ("notes", |r| r.notes = "bell\u{7}".into()),
            ("id", |r| r.id = "a b".into()),
            ("lat_deg", |r| r.lat_deg = 95.0),
            ("lon_deg", |r| r.lon_deg = f64::NAN),
            ("ground_elev_m", |r| r.ground_elev_m = 1e6),
            ("height_m", |r| r.height_m = -3.0),
            ("base_width_m", |r| r.base_width_m = Some(0.0)),
            ("sigma_horizontal_m", |r| r.sigma_horizontal_m = Some(-1.0)),
            ("sigma_vertical_m", |r| {
                r.sigma_vertical_m = Some(f64::INFINITY)
            }),
        ];
        for (field, spoil) in cases {
            let mut r = good();
            spoil(&mut r);
            let e = validate(&r).expect_err(field);
            assert_eq!(e.field, field);
        }
    }
}
