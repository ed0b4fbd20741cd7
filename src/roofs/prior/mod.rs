//! The roof prior around the core's learner (`citymesh_core::roof_prior`, docs/extensions.md
//! section 4): fitted per area of the source's data and kept in memory; its predictions as
//! GeoJSON properties and its report as text (`citymesh infer-roofs` writes both).

use citymesh_core::osm::BuildingRecord;
use citymesh_core::roof_image::RoofClass;
use citymesh_core::roof_prior::{APPLY_THRESHOLD, PriorReport, RoofPrior};
use serde_json::{Map, Value, json};

/// The prediction of an untagged building as GeoJSON properties: `roof_shape` (the most probable
/// class), `probability`, `probabilities`, and `applied` with `drawn`: whether citymesh draws
/// the class (the prior did not abstain and the probability reaches the threshold) or the
/// default.
pub fn prediction_properties(prior: &RoofPrior, record: &BuildingRecord) -> Map<String, Value> {
    let mut m = Map::new();
    if let (Some((class, p)), Some(all)) = (
        prior.prediction(&record.id),
        prior.probabilities(&record.id),
    ) {
        let applied = prior.is_applied() && p >= APPLY_THRESHOLD;
        m.insert("roof_shape".into(), json!(class.name()));
        m.insert("probability".into(), json!(round4(p)));
        m.insert(
            "probabilities".into(),
            json!(
                RoofClass::ALL
                    .iter()
                    .map(|c| (c.name().to_owned(), round4(all[c.index()])))
                    .collect::<Map<_, _>>()
            ),
        );
        m.insert("applied".into(), json!(applied));
        m.insert(
            "drawn".into(),
            json!(if applied { class.name() } else { "flat" }),
        );
    }
    m
}

fn round4(p: f32) -> Value {
    json!((f64::from(p) * 1e4).round() / 1e4)
}

/// The report as a few lines of text.
pub fn describe(r: &PriorReport) -> String {
    let [f, g, h] = r.tagged_per_class;
    let mut out = format!(
        "roof prior {}: {} buildings, {} tagged (flat {f}, gabled {g}, hipped {h}), {} untagged predicted",
        r.identity, r.buildings, r.tagged, r.predicted
    );
    if let (Some(acc), Some(correct), Some(confusion)) = (
        r.cross_validated_accuracy,
        r.cross_validated_correct,
        &r.confusion,
    ) {
        out.push_str(&format!(
            "\ncross-validated accuracy on the tagged: {:.1} % ({correct} of {}); the most common class alone: {:.1} %\nconfusion (rows true flat, gabled, hipped; columns predicted): {confusion:?}",
            100.0 * acc,
            r.tagged,
            100.0 * r.majority_share
        ));
    }
    out.push_str(&format!("\npredictions from: {}", r.predictor));
    match &r.abstained {
        Some(why) => out.push_str(&format!("\nabstains (roofs stay flat): {why}")),
        None => out.push_str(&format!(
            "\napplied to predictions of probability >= {APPLY_THRESHOLD}"
        )),
    }
    out
}
