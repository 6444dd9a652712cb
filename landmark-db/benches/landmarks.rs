//! The landmark database at 100,000 towers: CSV import into a file database
//! (WAL, synchronous=FULL, one transaction), and the radius query.
//!
//! `cargo bench -p towernav-landmark-db --bench landmarks`

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use towernav_geometry::GeoIndex;
use towernav_geometry::Geodetic;
use towernav_landmark_db::{Author, LandmarkDb, export_csv, import_csv};
use towernav_protocol::{LandmarkRecord, TowerType};

const N: usize = 100_000;

/// A 100,000-tower grid of lines about 250 m apart over roughly 80 km x 80 km.
fn towers() -> Vec<LandmarkRecord> {
    (0..N)
        .map(|i| {
            let (row, col) = ((i / 316) as f64, (i % 316) as f64);
            LandmarkRecord::new(
                format!("T{i}"),
                TowerType::ALL[i % 4],
                30.0 + row * 0.00225,
                114.0 + col * 0.0026,
                20.0 + (i % 50) as f64,
                30.0 + (i % 25) as f64,
            )
        })
        .collect()
}

fn benches(c: &mut Criterion) {
    let records = towers();
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("towers.csv");
    export_csv(&records, std::fs::File::create(&csv).expect("create csv")).expect("write csv");

    let mut group = c.benchmark_group("landmark_db");
    group.sample_size(10);
    group.throughput(Throughput::Elements(N as u64));
    let mut run = 0;
    group.bench_function("import_csv_100k", |b| {
        b.iter_batched(
            || {
                run += 1;
                LandmarkDb::open(&dir.path().join(format!("bench{run}.sqlite"))).expect("open")
            },
            |mut db| {
                import_csv(
                    &mut db,
                    &csv,
                    &Author {
                        by: "bench".into(),
                        at_unix_s: 0,
                    },
                )
                .expect("import")
            },
            BatchSize::PerIteration,
        )
    });
    let feet: Vec<_> = records.iter().map(|r| r.foot()).collect();
    group.bench_function("build_index_100k", |b| {
        b.iter(|| GeoIndex::from_points(&feet).len())
    });
    group.finish();

    let index = GeoIndex::from_points(&feet);
    let centre = Geodetic {
        lat_deg: 30.4,
        lon_deg: 114.4,
        height_m: 40.0,
    };
    let mut group = c.benchmark_group("landmark_db");
    group.bench_function("within_2km_of_100k", |b| {
        b.iter(|| index.within(&centre, 2000.0).len())
    });
    group.finish();
}

criterion_group!(landmarks, benches);
criterion_main!(landmarks);
