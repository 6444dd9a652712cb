//! Scoring a run against the simulator's truth (pure).

/// Horizontal error statistics, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    pub count: usize,
    pub rms: f64,
    pub median: f64,
    pub p95: f64,
    pub max: f64,
    /// Share of errors of 5 m or less.
    pub within_5m: f64,
}

pub fn error_stats(errors: &[f64]) -> ErrorStats {
    if errors.is_empty() {
        return ErrorStats::default();
    }
    let mut sorted = errors.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rms = (sorted.iter().map(|e| e * e).sum::<f64>() / sorted.len() as f64).sqrt();
    let rank = |q: f64| ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    ErrorStats {
        count: sorted.len(),
        rms,
        median: sorted[rank(0.5) - 1],
        p95: sorted[rank(0.95) - 1],
        max: sorted[sorted.len() - 1],
        within_5m: sorted.iter().filter(|e| **e <= 5.0).count() as f64 / sorted.len() as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_known_errors() {
        let errors: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = error_stats(&errors);
        assert_eq!(s.count, 100);
        assert_eq!(s.p95, 95.0);
        assert_eq!(s.median, 50.0);
        assert!((s.within_5m - 0.05).abs() < 1e-12);
        assert_eq!(s.max, 100.0);
        assert!((s.rms - (338350.0f64 / 100.0).sqrt()).abs() < 1e-9);
        assert_eq!(error_stats(&[]), ErrorStats::default());
    }
}
