use super::*;

#[test]
fn a_flood_logs_once_per_interval_and_counts_the_rest() {
    let t0 = Instant::now();
    let mut limit = LogLimiter::new(Duration::from_secs(10));
    assert_eq!(limit.allow(t0), Some(0));
    for i in 1..=1000 {
        assert_eq!(limit.allow(t0 + Duration::from_millis(i)), None);
    }
    assert_eq!(limit.allow(t0 + Duration::from_secs(10)), Some(1000));
    assert_eq!(limit.allow(t0 + Duration::from_secs(11)), None);
}
