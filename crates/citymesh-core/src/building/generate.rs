//! From OSM building records to meshed volumes, one cluster at a time: footprints in the local
//! frame, parameters from tags, the roof over the whole outline, heights over the ground, parts cut
//! out of their outline, truncation at the scene border, and the group mesh. A record that cannot
//! be built is skipped with a reason; the others still render.

use super::axes::RoofAxes;
use super::cluster::part_of;
use super::coverage::{floor_areas, uncovered_area};
use super::feature::{BuildingFeature, Quality};
use super::footprint::{Footprint, FootprintError, FootprintRing, NodeKey};
use super::group::{Volume, mesh_group};
use super::height_base::HeightBase;
use super::overlap::cut_by_smaller;
use super::params::BuildingParams;
use super::pieces::{Pieces, cut_out, truncate};
use super::roof::RoofShape;
use super::roof_method::RoofMethod;
use super::roof_surface::RoofSurface;
use super::skeleton_roof::SkeletonRoof;
use super::stats::{BuildingStats, MAX_AREA_LOSS_M2};
use super::tags::BuildingTags;
use crate::geo::{GeoBbox, LocalFrame};
use crate::mesh::{Mesh, check_closed, check_manifold};
use crate::osm::{BuildingRecord, OsmId, Ring};
use crate::terrain::ElevationModel;
use foldhash::HashMap;
use std::collections::BTreeMap;

/// What every building of a scene is generated against.
pub struct BuildingContext<'a> {
    pub frame: &'a LocalFrame,
    pub elevation: &'a ElevationModel,
    /// Truncate buildings at this box (`/scene.glb`); `None` keeps them whole (tiles).
    pub clip: Option<GeoBbox>,
    /// The ground `height` is counted from.
    pub heights: HeightBase,
    /// How hipped, gabled and pyramidal roofs are laid over their footprints.
    pub roof_method: RoofMethod,
    /// Whether each building carries every OSM tag too.
    pub tags: super::TagProperties,
}

/// One record turned into footprints (one per outer ring) and parameters.
struct Prepared<'r> {
    record: &'r BuildingRecord,
    /// Each outer ring with its courtyards, in metres.
    footprints: Vec<Footprint>,
    /// For each footprint, the courtyards it could not keep as holes (they touch its outline
    /// or another courtyard): they are cut out of it.
    apart: Vec<Vec<FootprintRing>>,
    tags: BuildingTags,
}

/// Generates the buildings of one cluster into `mesh`, counting into `stats`.
pub fn generate_cluster(
    records: &[&BuildingRecord],
    ctx: &BuildingContext,
    mesh: &mut Mesh,
    stats: &mut BuildingStats,
) {
    generate_cluster_until(records, ctx, mesh, stats, &|| false);
}

/// [`generate_cluster`], asking `stop` before each building and before meshing the group; when
/// it says so the cluster is left unfinished (the caller drops the scene).
pub fn generate_cluster_until(
    records: &[&BuildingRecord],
    ctx: &BuildingContext,
    mesh: &mut Mesh,
    stats: &mut BuildingStats,
    stop: &(dyn Fn() -> bool + Sync),
) {
    let (first_feature, first_repair) = (stats.features.len(), stats.repaired_ids.len());
    let mut prepared: Vec<Prepared> = Vec::with_capacity(records.len());
    for &record in records {
        if stop() {
            return;
        }
        match prepare(record, ctx.frame) {
            Ok(p) => prepared.push(p),
            Err(e) => stats.skip(record.id, footprint_reason(e)),
        }
    }

    // Which outline each part stands in.
    let outline_of: Vec<Option<usize>> = prepared
        .iter()
        .map(|p| {
            if !p.record.is_part {
                return None;
            }
            prepared
                .iter()
                .position(|o| !o.record.is_part && part_of(p.record, o.record))
        })
        .collect();

    // Outlines drawn over each other: the smaller is cut out of the larger.
    let overlapping = cut_by_smaller(
        &prepared
            .iter()
            .map(|p| (&p.footprints[..], p.record.is_part))
            .collect::<Vec<_>>(),
    );

    let mut roofs: Vec<RoofSurface> = Vec::new();
    // The record each roof belongs to.
    let mut roof_ids: Vec<OsmId> = Vec::new();
    let mut volumes: Vec<Volume> = Vec::new();
    // The floor area each building's pieces leave, by feature.
    let mut wanted: BTreeMap<u32, f64> = BTreeMap::new();
    for (i, p) in prepared.iter().enumerate() {
        if stop() {
            return;
        }
        // Every part standing in this outline is cut out of it, also one that stands on the
        // ground of another outline overlapping this one.
        let parts: Vec<&Prepared> = if p.record.is_part {
            Vec::new()
        } else {
            prepared
                .iter()
                .filter(|q| q.record.is_part && part_of(q.record, p.record))
                .collect()
        };
        // Parts stand on the ground of their outline, so they line up.
        let ground_ring = match outline_of[i] {
            Some(o) => &prepared[o].record.outers,
            None => &p.record.outers,
        };
        stats.invalid_tags += p.tags.invalid.len();
        // The record's row in the feature list, if it produces a volume.
        let feature = stats.features.len() as u32;
        let mut first_params: Option<BuildingParams> = None;
        for (k, footprint) in p.footprints.iter().enumerate() {
            let Some((surface, params, on_rectangle)) =
                roof_and_params(p, footprint, ctx.roof_method)
            else {
                stats.skip(p.record.id, "degenerate_footprint");
                continue;
            };
            if on_rectangle {
                stats
                    .repaired_ids
                    .push((p.record.id.to_string(), "roof_on_virtual_rectangle"));
            }
            let ring: Vec<(f64, f64)> = ground_ring
                .get(k)
                .or(ground_ring.first())
                .map(|r| r.nodes.iter().map(|n| (n.lon, n.lat)).collect())
                .unwrap_or_default();
            let (elev_min, elev_max) = ctx.elevation.height_range_along(&ring);
            let floor = elev_min + params.min_height;
            let top = ctx.heights.top(elev_min, elev_max, params.height);
            let surface = surface.with_heights(top, params.roof_height);

            // Outline minus its parts and the courtyards set apart, then truncated at the scene
            // border.
            let apart = &p.apart[k];
            let over = &overlapping[i];
            let mut pieces = Pieces::whole(footprint);
            if !parts.is_empty() || !apart.is_empty() || !over.is_empty() {
                let cut: Vec<&Footprint> = parts
                    .iter()
                    .copied()
                    .chain(over.iter().map(|&j| &prepared[j]))
                    .flat_map(|q| &q.footprints)
                    .collect();
                pieces = cut_out(footprint, &cut, apart);
                if !over.is_empty() {
                    stats
                        .repaired_ids
                        .push((p.record.id.to_string(), "overlap_cut_out"));
                }
                if pieces.footprints.is_empty() && !parts.is_empty() {
                    stats.outlines_covered_by_parts += 1;
                }
                if !apart.is_empty() {
                    stats
                        .repaired_ids
                        .push((p.record.id.to_string(), "courtyard_touches_a_ring"));
                }
            }
            if let Some(clip) = ctx.clip {
                let lo = ctx.frame.to_local(clip.min_lon(), clip.min_lat(), 0.0);
                let hi = ctx.frame.to_local(clip.max_lon(), clip.max_lat(), 0.0);
                let mut clipped = Pieces::default();
                for f in pieces.footprints {
                    clipped.extend(truncate(f, [lo[0], lo[1]], [hi[0], hi[1]]));
                }
                clipped.split |= pieces.split;
                pieces = clipped;
            }
            if pieces.split {
                stats
                    .repaired_ids
                    .push((p.record.id.to_string(), "split_where_rings_touch"));
            }
            *wanted.entry(feature).or_default() += pieces.area;
            if pieces.footprints.is_empty() {
                continue;
            }
            roofs.push(surface);
            roof_ids.push(p.record.id);
            for piece in pieces.footprints {
                volumes.push(Volume {
                    footprint: piece,
                    roof: roofs.len() - 1,
                    floor,
                    wall_colour: params.wall_colour,
                    roof_colour: params.roof_colour,
                    feature,
                });
            }
            if k == 0 {
                stats.count(p.record.is_part, &params);
                if let Some(super::tags::ShapeTag::Unsupported(value)) = &p.tags.roof_shape {
                    stats
                        .unsupported_shape_ids
                        .push((p.record.id.to_string(), value.clone()));
                }
            }
            first_params.get_or_insert(params);
        }
        if let Some(params) = first_params {
            stats.generated += 1;
            let feature = BuildingFeature::new(p.record, &p.tags, &params);
            stats.features.push(match ctx.tags {
                super::TagProperties::Named => feature,
                super::TagProperties::All => feature.with_every_tag(&p.record.tags),
            });
        }
    }
    if stop() {
        return;
    }
    let (positions, triangles) = (mesh.positions.len(), mesh.triangles.len());
    let mut report = mesh_group(&volumes, &roofs, mesh);
    // A sloped roof over a courtyard, or one cut into many faces (sampled curves, sawtooth) over
    // a sliver of a footprint, can be cut so finely that the triangulation leaves a sliver
    // (found by fuzzing and property tests). Such groups are checked; one that is not closed is
    // built again with those roofs flat, and each flattened roof is reported.
    let risky: Vec<usize> = volumes
        .iter()
        .filter(|v| {
            let roof = &roofs[v.roof];
            !roof.is_planar() && (!v.footprint.holes.is_empty() || roof.shape.has_many_faces())
        })
        .map(|v| v.roof)
        .collect();
    // Open edges or slivers are the fault; edges shared by four faces where buildings touch at
    // a corner are not.
    let broken = |mesh: &Mesh| {
        let r = check_closed(mesh, triangles..mesh.triangles.len());
        r.open_edges > 0 || r.degenerate > 0
    };
    if !risky.is_empty() && broken(mesh) {
        mesh.positions.truncate(positions);
        mesh.triangles.truncate(triangles);
        mesh.styles.truncate(triangles);
        for &r in &risky {
            // No rise: flat at the roof's top.
            roofs[r].roof_height = 0.0;
        }
        let mut flattened: Vec<OsmId> = risky.iter().map(|&r| roof_ids[r]).collect();
        flattened.dedup();
        for id in flattened {
            stats.repaired_ids.push((id.to_string(), "roof_flattened"));
        }
        report = mesh_group(&volumes, &roofs, mesh);
    }
    stats.shared_walls += report.shared_edges;
    stats.dropped_constraints += report.dropped_constraints;
    // Nothing dropped unreported: every building's floor covers what its outline leaves.
    let drawn = floor_areas(mesh, triangles..mesh.triangles.len());
    for (feature, lost) in uncovered_area(&wanted, &drawn, MAX_AREA_LOSS_M2) {
        if let Some(f) = stats.features.get(feature as usize) {
            let id = f.id.to_string();
            stats.area_lost_ids.push((id, (lost * 10.0).round() / 10.0));
        }
    }
    // Each building's quality record: its group's surface, its solids, its repairs, its areas.
    let group = triangles..mesh.triangles.len();
    let solids = check_manifold(mesh, group.clone());
    // A building is a strict 2-manifold when every solid its triangles belong to is.
    let mut strict: HashMap<u32, bool> = HashMap::default();
    for (t, &ok) in group.zip(&solids.strict) {
        *strict.entry(mesh.styles[t].feature).or_insert(true) &= ok;
    }
    let repaired = &stats.repaired_ids[first_repair..];
    for (row, f) in stats.features.iter_mut().enumerate().skip(first_feature) {
        let row = row as u32;
        let id = f.id.to_string();
        f.quality = Quality {
            closed: solids.report.open_edges == 0,
            strict_manifold: solids.report.open_edges == 0
                && strict.get(&row).copied().unwrap_or(false),
            repairs: repaired
                .iter()
                .filter(|(r, _)| *r == id)
                .map(|(_, what)| *what)
                .collect(),
            // To 0.01 m²: what the data's precision carries.
            floor_area: hundredths(drawn.get(&row).copied().unwrap_or(0.0)),
            outline_area: hundredths(wanted.get(&row).copied().unwrap_or(0.0)),
        };
        f.quality.repairs.dedup();
    }
}

fn hundredths(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

/// A record's footprint and heights as the generator builds it (from its first outer ring's
/// roof), without building it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordOutline {
    /// Footprint area, m² (courtyards left out).
    pub area: f64,
    /// Total height above the ground, m.
    pub height: f64,
    /// Height of the lowest floor above the ground, m.
    pub min_height: f64,
    /// Roof rise from eaves to top, m.
    pub roof_height: f64,
}

/// The outline of `record` in `frame`, its roof laid as `roof_method` says, or `None` when it
/// cannot be built.
pub fn record_outline(
    record: &BuildingRecord,
    frame: &LocalFrame,
    roof_method: RoofMethod,
) -> Option<RecordOutline> {
    let p = prepare(record, frame).ok()?;
    let (_, params, _) = roof_and_params(&p, p.footprints.first()?, roof_method)?;
    Some(RecordOutline {
        area: p.footprints.iter().map(Footprint::area).sum(),
        height: params.height,
        min_height: params.min_height,
        roof_height: params.roof_height,
    })
}

/// The roof over one footprint of `p` (before heights), the parameters under it, and whether a
/// roof `roof_method` lays over the straight skeleton had to keep the virtual rectangle (the
/// footprint has more than [`super::straight_skeleton::MAX_SKELETON_VERTICES`] vertices, or its
/// skeleton could not be built); `None` when the footprint has no axes.
fn roof_and_params(
    p: &Prepared,
    footprint: &Footprint,
    roof_method: RoofMethod,
) -> Option<(RoofSurface, BuildingParams, bool)> {
    let axes = RoofAxes::of_ring(&footprint.outer.points).map(RoofAxes::long_first)?;
    let shape = params_shape(&p.tags);
    let wanted = roof_method.uses_skeleton(shape, footprint, &axes);
    let skeleton = wanted
        .then(|| match shape {
            RoofShape::Gabled => SkeletonRoof::gabled(footprint),
            _ => SkeletonRoof::hipped(footprint),
        })
        .and_then(Result::ok);
    let on_rectangle = wanted && skeleton.is_none();
    let surface = match skeleton {
        Some(roof) => RoofSurface::over_skeleton(shape, axes, roof),
        None => RoofSurface::new(
            shape,
            axes,
            p.tags.orientation,
            &footprint.outer.points,
            p.tags.direction,
            None,
        ),
    };
    let params = BuildingParams::new(&p.tags, surface.run());
    Some((surface, params, on_rectangle))
}

fn params_shape(tags: &BuildingTags) -> RoofShape {
    match &tags.roof_shape {
        Some(super::tags::ShapeTag::Known(s)) => *s,
        _ => RoofShape::Flat,
    }
}

fn footprint_reason(e: FootprintError) -> &'static str {
    match e {
        FootprintError::TooFewPoints => "too_few_nodes",
        FootprintError::NoArea => "no_area",
        FootprintError::SelfIntersecting => "self_intersecting",
        FootprintError::NotFinite => "not_finite",
        FootprintError::TooManyVertices => "too_many_nodes",
        FootprintError::TooManyHoles => "too_many_holes",
    }
}

/// Projects a ring; keys are OSM node ids, or the exact lon/lat where the source has no ids.
fn project(ring: &Ring, frame: &LocalFrame) -> FootprintRing {
    let mut points = Vec::with_capacity(ring.nodes.len());
    let mut keys = Vec::with_capacity(ring.nodes.len());
    for n in &ring.nodes {
        let p = frame.to_local(n.lon, n.lat, 0.0);
        points.push([p[0], p[1]]);
        keys.push(match n.id {
            Some(id) => NodeKey::Osm(id),
            None => NodeKey::At(n.lon.to_bits(), n.lat.to_bits()),
        });
    }
    FootprintRing::new(points, keys)
}

fn prepare<'r>(
    record: &'r BuildingRecord,
    frame: &LocalFrame,
) -> Result<Prepared<'r>, FootprintError> {
    let inners: Vec<FootprintRing> = record.inners.iter().map(|r| project(r, frame)).collect();
    let mut footprints = Vec::with_capacity(record.outers.len());
    let mut apart = Vec::with_capacity(record.outers.len());
    let mut last_error = FootprintError::TooFewPoints;
    for outer in &record.outers {
        let outer = project(outer, frame);
        // Courtyards go with the outer ring that holds them.
        let holes: Vec<FootprintRing> = inners
            .iter()
            .filter(|h| {
                h.points
                    .first()
                    .is_some_and(|p| super::footprint::inside(&outer.points, *p))
            })
            .cloned()
            .collect();
        match Footprint::with_courtyards_apart(outer, holes) {
            Ok((f, a)) => {
                footprints.push(f);
                apart.push(a);
            }
            Err(e) => last_error = e,
        }
    }
    if footprints.is_empty() {
        return Err(last_error);
    }
    Ok(Prepared {
        record,
        tags: BuildingTags::read(&record.tags),
        footprints,
        apart,
    })
}
