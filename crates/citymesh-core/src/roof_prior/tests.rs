use super::*;
use crate::osm::{Ring, RingNode, Tags};

/// A `w` x `h` metre rectangle whose corner is `at` metres east and north of 8.4 E, 49.0 N.
pub(crate) fn building(
    id: i64,
    at: [f64; 2],
    w: f64,
    h: f64,
    tags: &[(&str, &str)],
) -> BuildingRecord {
    let frame = LocalFrame::new(8.4, 49.0, 0.0);
    let (mx, my) = frame.metres_per_degree();
    let nodes = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]
        .iter()
        .map(|p| RingNode {
            id: None,
            lon: 8.4 + (at[0] + p[0]) / mx,
            lat: 49.0 + (at[1] + p[1]) / my,
        })
        .collect();
    let mut t = Tags::new();
    for (k, v) in tags {
        t.insert((*k).into(), (*v).into());
    }
    BuildingRecord {
        id: OsmId::Way(id),
        is_part: false,
        outers: vec![Ring { nodes }],
        inners: Vec::new(),
        tags: t,
    }
}

/// A district of 300 buildings on a 30 m grid: houses (12 x 9 m) are gabled in the west half and
/// hipped in the east half, garages (6 x 3 m) and offices (40 x 30 m) are flat. Every third
/// building is untagged.
fn district() -> Vec<BuildingRecord> {
    let mut records = Vec::new();
    for i in 0..300i64 {
        let (col, row) = (i % 20, i / 20);
        let at = [30.0 * col as f64, 30.0 * row as f64];
        let (kind, w, h, shape) = match i % 5 {
            0 => ("garage", 6.0, 3.0, "flat"),
            1 => ("office", 40.0 * 0.6, 30.0 * 0.6, "flat"),
            _ if col < 10 => ("house", 12.0, 9.0, "gabled"),
            _ => ("house", 12.0, 9.0, "hipped"),
        };
        let mut tags = vec![("building", kind)];
        if i % 3 != 0 {
            tags.push(("roof:shape", shape));
        }
        records.push(building(i + 1, at, w, h, &tags));
    }
    records
}

fn truth(i: i64) -> RoofClass {
    let col = (i - 1) % 20;
    match (i - 1) % 5 {
        0 | 1 => RoofClass::Flat,
        _ if col < 10 => RoofClass::Gabled,
        _ => RoofClass::Hipped,
    }
}

#[test]
fn learns_a_district_and_predicts_its_untagged_buildings() {
    let records = district();
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let prior = RoofPrior::fit(&refs);
    let r = &prior.report;
    assert_eq!((r.buildings, r.tagged, r.predicted), (300, 200, 100));
    assert_eq!(r.abstained, None, "{r:?}");
    // The untagged buildings are every third: their classes follow the same rule.
    let mut right = 0;
    for id in prior.predicted_ids() {
        let OsmId::Way(i) = id else { unreachable!() };
        let (class, p) = prior.prediction(&id).unwrap();
        assert!((1.0 / 3.0..=1.0).contains(&p));
        if class == truth(i) {
            right += 1;
        }
    }
    assert!(right >= 95, "{right} of 100 right");
    assert!(r.cross_validated_accuracy.unwrap() >= 0.95, "{r:?}");
    assert_eq!(
        r.confusion
            .as_ref()
            .unwrap()
            .iter()
            .flatten()
            .sum::<usize>(),
        200
    );
    assert!(prior.probabilities(&OsmId::Way(2)).is_none(), "tagged");
}

#[test]
fn the_same_records_give_the_same_prior_and_a_changed_tag_a_new_identity() {
    let records = district();
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let a = RoofPrior::fit(&refs);
    let mut reversed = refs.clone();
    reversed.reverse();
    let b = RoofPrior::fit(&reversed);
    assert_eq!(a.report, b.report);
    for id in a.predicted_ids() {
        assert_eq!(a.probabilities(&id), b.probabilities(&id));
    }
    let mut changed = district();
    changed[1].tags.insert("roof:shape".into(), "gabled".into());
    let refs: Vec<&BuildingRecord> = changed.iter().collect();
    assert_ne!(RoofPrior::fit(&refs).report.identity, a.report.identity);
}

#[test]
fn abstains_with_too_few_tags_or_no_better_than_the_majority() {
    let records: Vec<BuildingRecord> = district().into_iter().take(40).collect();
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let few = RoofPrior::fit(&refs);
    assert_eq!(few.report.tagged, 26);
    assert!(
        few.report
            .abstained
            .as_deref()
            .unwrap()
            .contains("at least 30")
    );
    assert!(!few.is_applied());
    assert_eq!(few.report.predicted, 14, "predicted, but not applied");
    let records: Vec<BuildingRecord> = district().into_iter().take(12).collect();
    let refs: Vec<&BuildingRecord> = records.iter().collect();
    let none = RoofPrior::fit(&refs);
    assert_eq!((none.report.tagged, none.report.predicted), (8, 0));
    // Twelve gabled houses and four untagged ones: one class, predicted but not applied.
    let one: Vec<BuildingRecord> = (0..16i64)
        .map(|i| {
            let mut tags = vec![("building", "house")];
            if i < 12 {
                tags.push(("roof:shape", "gabled"));
            }
            building(i + 1, [25.0 * i as f64, 0.0], 12.0, 9.0, &tags)
        })
        .collect();
    let refs: Vec<&BuildingRecord> = one.iter().collect();
    let single = RoofPrior::fit(&refs);
    assert!(
        single
            .report
            .abstained
            .as_deref()
            .unwrap()
            .contains("1 roof classes")
    );
    assert_eq!(single.report.predicted, 4);
    assert_eq!(single.report.predictor, "class_shares");
    for id in single.predicted_ids() {
        assert_eq!(single.prediction(&id).unwrap().0, RoofClass::Gabled);
    }

    // Shapes that nothing predicts: identical houses, flat or gabled by a coin that the
    // features cannot see.
    let noise: Vec<BuildingRecord> = (0..200i64)
        .map(|i| {
            let coin = xxhash_rust::xxh3::xxh3_64(&i.to_le_bytes()) % 2;
            let shape = if coin == 0 { "flat" } else { "gabled" };
            let at = [25.0 * (i % 15) as f64, 25.0 * (i / 15) as f64];
            building(
                i + 1,
                at,
                10.0,
                10.0,
                &[("building", "yes"), ("roof:shape", shape)],
            )
        })
        .collect();
    let refs: Vec<&BuildingRecord> = noise.iter().collect();
    let blind = RoofPrior::fit(&refs);
    assert!(
        blind
            .report
            .abstained
            .as_deref()
            .unwrap()
            .contains("does not beat"),
        "{:?}",
        blind.report
    );
    // Its predictions are then the tagged classes' shares, the same everywhere.
    assert_eq!(blind.report.predictor, "class_shares");
    assert_eq!(few.report.predictor, "trees");
    assert_eq!(
        required_margin(0.5, 16),
        0.125,
        "the standard error of a share of 16"
    );
    assert_eq!(required_margin(0.5, 400), MIN_MARGIN);
}

#[test]
fn parts_and_compound_roofs_teach_nothing() {
    let mut part = building(1, [0.0, 0.0], 10.0, 10.0, &[("roof:shape", "gabled")]);
    part.is_part = true;
    let many = building(2, [0.0, 0.0], 10.0, 10.0, &[("roof:shape", "many")]);
    let skillion = building(3, [0.0, 0.0], 10.0, 10.0, &[("roof:shape", "skillion")]);
    let pyramidal = building(4, [0.0, 0.0], 10.0, 10.0, &[("roof:shape", "pyramidal")]);
    assert_eq!(tagged_class(&many), None);
    assert_eq!(tagged_class(&skillion), None);
    assert_eq!(tagged_class(&pyramidal), Some(RoofClass::Hipped));
    let prior = RoofPrior::fit(&[&part, &many, &skillion, &pyramidal]);
    assert_eq!((prior.report.buildings, prior.report.tagged), (3, 1));
    assert_eq!(feature_names().len(), {
        let o = features::Outline::of(&pyramidal, &LocalFrame::new(8.4, 49.0, 0.0)).unwrap();
        own_features(&pyramidal, &o).len() + neighbour_feature_names().len()
    });
}

#[test]
fn combining_multiplies_and_normalises() {
    let c = combine([0.5, 0.3, 0.2], [0.2, 0.6, 0.2]);
    // 0.10, 0.18, 0.04 over 0.32.
    let want = [0.3125, 0.5625, 0.125];
    for (a, b) in c.iter().zip(want) {
        assert!((a - b).abs() < 1e-6, "{c:?}");
    }
    assert_eq!(combine([0.5, 0.5, 0.0], [0.0, 0.0, 1.0]), [0.5, 0.5, 0.0]);
    let uniform = combine([0.7, 0.2, 0.1], [1.0 / 3.0; 3]);
    assert!((uniform[0] - 0.7).abs() < 1e-6);
}
