//! The synthetic scene: exact counts, determinism, exact bounds and quantization, a plausible mix.

use pointlet_core::{flags, PointBatch};
use pointlet_io::generate::{SceneConfig, SceneGenerator, EPSG_UTM};
use pointlet_io::PointReader;

fn generator(points: u64, seed: u64) -> SceneGenerator {
    SceneGenerator::new(SceneConfig { points, seed })
}

/// Every point, read `batch` at a time; checks each batch's size and shape on the way.
fn read_all(g: &SceneGenerator, batch: usize) -> PointBatch {
    let mut r = g.reader();
    let mut all = PointBatch::new(r.meta().layout);
    while let Some(b) = r.read_batch(batch).expect("generated batch") {
        assert!(
            !b.is_empty() && b.len() <= batch,
            "batch of {} for max {batch}",
            b.len()
        );
        b.check_shape().expect("batch shape");
        assert_eq!(b.layout, all.layout);
        for i in 0..b.len() {
            all.push_from(&b, i);
        }
    }
    assert!(r.read_batch(batch).expect("after the end").is_none());
    all
}

#[test]
fn same_points_whatever_the_batch_size_or_instance() {
    let a = read_all(&generator(123_457, 11), 7);
    let b = read_all(&generator(123_457, 11), 1000);
    let c = read_all(&generator(123_457, 11), 1 << 20);
    assert_eq!(a.len(), 123_457);
    assert!(a == b, "batches of 7 and 1000 differ");
    assert!(a == c, "batches of 7 and 2^20 differ");
}

#[test]
fn exact_counts_for_awkward_sizes() {
    for points in [1u64, 2, 999, 123_457] {
        let g = generator(points, 3);
        assert_eq!(g.meta().point_count, points);
        assert_eq!(read_all(&g, 4096).len() as u64, points);
    }
    assert_eq!(read_all(&generator(50_001, 3), 50_000).len(), 50_001);
}

#[test]
fn zero_sized_requests_and_an_empty_scene() {
    let g = generator(10, 1);
    let mut r = g.reader();
    let empty = r.read_batch(0).expect("max 0").expect("points remain");
    assert!(empty.is_empty());
    assert_eq!(r.read_batch(100).expect("rest").expect("ten").len(), 10);
    assert!(r.read_batch(0).expect("max 0 at the end").is_none());
    assert!(generator(0, 1)
        .reader()
        .read_batch(10)
        .expect("none")
        .is_none());
}

#[test]
fn header_describes_a_georeferenced_format_3_scene() {
    let g = generator(1_000_000, 1);
    let m = g.meta();
    assert_eq!(m.format, "synthetic scene");
    assert_eq!(m.las_point_format, Some(3));
    assert!(m.layout.gps_time && m.layout.rgb && !m.layout.nir && !m.layout.waveform);
    let q = m.quantization.expect("quantization");
    assert_eq!(q.scale, [0.001; 3]);
    assert_eq!(q.offset, m.bounds.min, "offset at the scene's corner");
    assert_eq!(m.vlrs.len(), 1);
    let crs = &m.vlrs[0];
    assert!(crs.is_crs() && crs.record_id == 34735);
    let words: Vec<u16> = crs
        .data
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    assert!(words
        .chunks(4)
        .skip(1)
        .any(|k| k[0] == 3072 && k[3] == EPSG_UTM));
    // About 20 points per m²: a million points cover about 5 ha.
    let e = m.bounds.extent();
    let area = e[0] * e[1];
    assert!((area - 50_000.0).abs() < 500.0, "area {area}");
    assert!((499_000.0..501_000.0).contains(&m.bounds.min[0]));
    assert!((4_099_000.0..4_101_000.0).contains(&m.bounds.min[1]));
    assert!(m.bounds.min[2] > 100.0 && m.bounds.max[2] < 500.0);
    assert!(g.reader().path().display().to_string().contains("1000000"));
}

#[test]
fn bounds_are_exact_and_coordinates_survive_quantization() {
    for points in [1u64, 2, 5_000, 300_000] {
        let g = generator(points, 5);
        let m = g.meta();
        let q = m.quantization.expect("quantization");
        let pts = read_all(&g, 1 << 16);
        let mut bounds = pointlet_core::Aabb::EMPTY;
        for p in &pts.xyz {
            assert!(m.bounds.contains(*p), "{p:?} outside {:?}", m.bounds);
            let raw = q.quantize(*p).expect("quantizable");
            let back = q.dequantize(raw);
            assert!(
                (0..3).all(|i| back[i].to_bits() == p[i].to_bits()),
                "{p:?} is not exactly representable"
            );
            bounds.grow(*p);
        }
        assert_eq!(
            bounds, m.bounds,
            "declared bounds of {points} points are not tight"
        );
    }
}

#[test]
fn a_town_with_fields_and_woods_and_consistent_returns() {
    for seed in [1u64, 2, 3] {
        let pts = read_all(&generator(2_000_000, seed), 1 << 20);
        let mut classes = [0usize; 32];
        for (i, &c) in pts.classification.iter().enumerate() {
            classes[c as usize] += 1;
            let (ret, of) = (pts.returns[i] & 15, pts.returns[i] >> 4);
            assert!(
                ret >= 1 && of >= 1 && ret <= of && of <= 5,
                "return {ret} of {of}"
            );
            let a = pts.scan_angle[i];
            assert!(a.abs() <= 30.0 && a.fract() == 0.0, "scan angle {a}");
            assert!(pts.point_source_id[i] >= 1);
            assert!(pts.gps_time[i] > 3.0e8);
        }
        let share =
            |c: &[usize]| c.iter().map(|k| classes[*k]).sum::<usize>() as f64 / pts.len() as f64;
        let (ground, building, vegetation) = (share(&[2, 9, 11]), share(&[6]), share(&[3, 4, 5]));
        let noise = share(&[7, 18]);
        let msg = format!("seed {seed}: classes {classes:?}");
        assert!((0.3..0.9).contains(&ground), "{msg}");
        assert!((0.01..0.4).contains(&building), "{msg}");
        assert!((0.05..0.6).contains(&vegetation), "{msg}");
        assert!(noise > 0.0 && noise < 0.001, "{msg}");
        assert_eq!(ground + building + vegetation + noise, 1.0, "{msg}");
        // Multiple returns: trees split pulses, and some of their last returns reach the ground.
        let multi = pts.returns.iter().filter(|r| *r >> 4 > 1).count() as f64 / pts.len() as f64;
        assert!(multi > 0.05, "{msg}: multiple-return share {multi}");
        let ground_under = (0..pts.len())
            .filter(|&i| {
                pts.classification[i] == 2 && pts.returns[i] >> 4 > 1 && pts.returns[i] & 15 > 1
            })
            .count();
        assert!(
            ground_under > 1000,
            "{msg}: {ground_under} last returns on the ground"
        );
        let first_veg = (0..pts.len())
            .filter(|&i| pts.classification[i] == 5 && pts.returns[i] & 15 == 1)
            .count();
        assert!(first_veg > 1000, "{msg}");
        assert!(pts
            .flags
            .iter()
            .any(|f| f & flags::EDGE_OF_FLIGHT_LINE != 0));
        assert!(pts.flags.iter().any(|f| f & flags::SCAN_DIRECTION != 0));
        assert!(pts.flags.iter().any(|f| f & flags::SCAN_DIRECTION == 0));
    }
}

#[test]
fn strips_are_flown_one_after_the_other() {
    // 4 M points: a 447 m square of 9×9 tiles, flown as strips of 6 and 3 tile columns.
    let pts = read_all(&generator(4_000_000, 4), 1 << 20);
    let strips: std::collections::BTreeSet<u16> = pts.point_source_id.iter().copied().collect();
    assert_eq!(strips.into_iter().collect::<Vec<_>>(), vec![1, 2]);
    let times = |id: u16| -> Vec<f64> {
        (0..pts.len())
            .filter(|&i| pts.point_source_id[i] == id)
            .map(|i| pts.gps_time[i])
            .collect()
    };
    let first_max = times(1).into_iter().fold(f64::MIN, f64::max);
    let second_min = times(2).into_iter().fold(f64::MAX, f64::min);
    assert!(second_min > first_max, "strip 2 starts before strip 1 ends");
    // Inside a tile time never goes back: backward steps only where a tile begins.
    let back = pts.gps_time.windows(2).filter(|w| w[1] < w[0]).count();
    assert!(
        back > 0 && back < 81,
        "{back} backward time steps for 81 tiles"
    );
    // Strip 1 flies north over the western 6/9 of the scene: east of its axis is its right.
    let axis = 500_000.0 + 447.214 * 3.0 / 9.0;
    for i in (0..pts.len()).filter(|&i| pts.point_source_id[i] == 1) {
        let (x, a) = (pts.xyz[i][0], pts.scan_angle[i]);
        assert!(a.abs() <= 30.0);
        if (x - axis).abs() > 5.0 {
            assert_eq!(a > 0.0, x > axis, "scan angle {a} at x {x}");
        }
    }
}

#[test]
fn thread_count_does_not_change_the_points() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        pool.install(|| read_all(&generator(300_000, 9), 100_000))
    };
    assert!(run(1) == run(3));
}

#[test]
fn different_seeds_give_different_scenes() {
    let a = read_all(&generator(20_000, 1), 1 << 20);
    let b = read_all(&generator(20_000, 2), 1 << 20);
    let same = a.xyz.iter().zip(&b.xyz).filter(|(p, q)| p == q).count();
    assert!(same < 10, "{same} identical positions");
    assert_ne!(a.rgb, b.rgb);
}

/// Throughput on one thread (no assertion on speed): run with
/// `cargo test --release -p pointlet-io --test generate -- --ignored --nocapture`.
#[test]
#[ignore]
fn throughput() {
    let points = 20_000_000u64;
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let (n, secs) = pool.install(|| {
            let start = std::time::Instant::now();
            let mut r = generator(points, 1).reader();
            let mut n = 0u64;
            while let Some(b) = r.read_batch(1 << 20).expect("batch") {
                n += b.len() as u64;
            }
            (n, start.elapsed().as_secs_f64())
        });
        assert_eq!(n, points);
        println!(
            "{threads} thread(s): {points} points in {secs:.2} s = {:.1} M points/s",
            points as f64 / secs / 1e6
        );
    }
}
