//! 3D Tiles over HTTP on the real Karlsruhe-Kirchfeld data: the tileset, the binary subtree
//! checked against the 3D Tiles 1.1 layout, content glb that the validator accepts, and a known
//! building corner decoded through the tileset's transforms back onto its OSM node.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code: failing is the point

use crate::common;

use axum::http::StatusCode;
use citymesh_core::building::set::BuildingSet;
use citymesh_core::geo::{ecef_to_geodetic, geodetic_to_ecef};
use citymesh_core::osm::read_buildings;
use common::{assert_valid_glb, dem_dir, get, osm_bytes};
use serde_json::Value;

async fn app(db: &tempfile::TempDir) -> axum::Router {
    common::kirchfeld_app(db).await
}

/// The region tree over Kirchfeld's extent (the tileset without a box is the world tileset).
fn over_extent(query: &str) -> String {
    let set = BuildingSet::new(
        read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings,
    );
    let extent = set.extent().unwrap();
    let sep = if query.is_empty() { "" } else { "&" };
    format!("/3dtiles/tileset.json?bbox={extent}{sep}{query}")
}

/// Morton index written out here, bit by bit (x in even bits, y in odd ones).
fn morton(x: u32, y: u32) -> usize {
    let mut m = 0usize;
    for b in 0..16 {
        m |= (((x >> b) & 1) as usize) << (2 * b);
        m |= (((y >> b) & 1) as usize) << (2 * b + 1);
    }
    m
}

struct Subtree {
    json: Value,
    binary: Vec<u8>,
}

/// Parses a subtree file, checking the header and the 8-byte alignment the spec requires.
fn parse_subtree(bytes: &[u8]) -> Subtree {
    assert_eq!(&bytes[0..4], b"subt", "magic");
    assert_eq!(
        u32::from_le_bytes(bytes[4..8].try_into().unwrap()),
        1,
        "version"
    );
    let json_len = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    let bin_len = u64::from_le_bytes(bytes[16..24].try_into().unwrap()) as usize;
    assert_eq!(json_len % 8, 0, "JSON chunk padded to 8 bytes");
    assert_eq!(bin_len % 8, 0, "binary chunk padded to 8 bytes");
    assert_eq!(bytes.len(), 24 + json_len + bin_len);
    let json: Value = serde_json::from_slice(&bytes[24..24 + json_len]).unwrap();
    let binary = bytes[24 + json_len..].to_vec();
    if let Some(views) = json["bufferViews"].as_array() {
        assert_eq!(json["buffers"][0]["byteLength"], bin_len);
        for v in views {
            assert_eq!(
                v["byteOffset"].as_u64().unwrap() % 8,
                0,
                "bufferView aligned to 8"
            );
        }
    }
    Subtree { json, binary }
}

/// The bits of an availability entry (a bitstream or a constant), `count` of them.
fn bits(s: &Subtree, entry: &Value, count: usize) -> Vec<bool> {
    if let Some(c) = entry.get("constant") {
        return vec![c == 1; count];
    }
    let view = &s.json["bufferViews"][entry["bitstream"].as_u64().unwrap() as usize];
    let offset = view["byteOffset"].as_u64().unwrap() as usize;
    let out: Vec<bool> = (0..count)
        .map(|i| s.binary[offset + i / 8] >> (i % 8) & 1 == 1)
        .collect();
    assert_eq!(
        out.iter().filter(|b| **b).count() as u64,
        entry["availableCount"].as_u64().unwrap()
    );
    out
}

#[tokio::test]
async fn the_tileset_subtree_and_content_follow_3d_tiles_1_1() {
    let db = tempfile::tempdir().unwrap();
    let app = app(&db).await;
    let t = get(&app, &over_extent("tiling=implicit")).await;
    assert_eq!(t.status, StatusCode::OK);
    let tileset = t.json();
    assert_eq!(tileset["asset"]["version"], "1.1");
    let root = &tileset["root"];
    let implicit = &root["implicitTiling"];
    assert_eq!(implicit["subdivisionScheme"], "QUADTREE");
    let levels = implicit["availableLevels"].as_u64().unwrap() as u8;
    assert_eq!(implicit["subtreeLevels"], levels);
    let region: Vec<f64> = root["boundingVolume"]["region"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    // The buildings' extent (data README: 8.3877,49.0390 - 8.4039,49.0640), in radians.
    let set = BuildingSet::new(
        read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf"))
            .unwrap()
            .buildings,
    );
    let extent = set.extent().unwrap();
    assert!((region[0] - extent.min_lon().to_radians()).abs() < 1e-12);
    assert!((region[3] - extent.max_lat().to_radians()).abs() < 1e-12);
    // Karlsruhe's ground is about 110-120 m; the highest roof reaches 129.38 m (above 130 m
    // before complex footprints' default roofs rose over their own wings, not their rectangle).
    assert!(region[4] < 110.0, "{region:?}");
    assert!((region[5] - 129.380).abs() < 1e-3, "{region:?}");
    let content_uri = root["content"]["uri"].as_str().unwrap();
    let subtree_uri = implicit["subtrees"]["uri"].as_str().unwrap();
    assert!(content_uri.ends_with("content/{level}/{x}/{y}.glb"));

    let subtree_path = format!(
        "/3dtiles/{}",
        subtree_uri
            .replace("{level}", "0")
            .replace("{x}", "0")
            .replace("{y}", "0")
    );
    let s = parse_subtree(&get(&app, &subtree_path).await.body);
    let leaf = levels - 1;
    let n = 1u32 << leaf;
    // Every tile exists and every leaf has content: ground everywhere, with the buildings whose
    // group's point it holds.
    let total: usize = (0..levels).map(|l| 1usize << (2 * l)).sum();
    let tiles = bits(&s, &s.json["tileAvailability"], total);
    let contents = bits(&s, &s.json["contentAvailability"][0], total);
    let leaf_offset: usize = (0..leaf).map(|l| 1usize << (2 * l)).sum();
    assert!(tiles.iter().all(|b| *b), "every tile is available");
    assert!(contents.iter().all(|b| *b), "every tile has content");
    // One subtree holds every level: no child subtrees.
    assert_eq!(s.json["childSubtreeAvailability"]["constant"], 0);

    // Each tile's bounding region is its tile metadata (TILE_BOUNDING_REGION in the schema).
    let class = &tileset["schema"]["classes"]["tile"]["properties"]["boundingRegion"];
    assert_eq!(class["semantic"], "TILE_BOUNDING_REGION");
    assert_eq!(
        (&class["componentType"], &class["count"]),
        (&"FLOAT64".into(), &6.into())
    );
    assert_eq!(s.json["tileMetadata"], 0);
    let table = &s.json["propertyTables"][0];
    assert_eq!(
        (&table["class"], table["count"].as_u64()),
        (&"tile".into(), Some(total as u64))
    );
    let view = &s.json["bufferViews"][table["properties"]["boundingRegion"]["values"]
        .as_u64()
        .unwrap() as usize];
    let at = view["byteOffset"].as_u64().unwrap() as usize;
    assert_eq!(view["byteLength"].as_u64().unwrap() as usize, total * 48);
    let regions: Vec<[f64; 6]> = s.binary[at..at + total * 48]
        .chunks_exact(48)
        .map(|r| {
            std::array::from_fn(|k| f64::from_le_bytes(r[8 * k..8 * k + 8].try_into().unwrap()))
        })
        .collect();
    let region_of = |level: u8, x: u32, y: u32| {
        let before: usize = (0..level).map(|l| 1usize << (2 * l)).sum();
        regions[before + morton(x, y)]
    };
    // Geometric errors (TILE_GEOMETRIC_ERROR): 0 at the leaves, a parent's at least its
    // children's.
    let error_view = &s.json["bufferViews"][table["properties"]["geometricError"]["values"]
        .as_u64()
        .unwrap() as usize];
    let at = error_view["byteOffset"].as_u64().unwrap() as usize;
    let errors: Vec<f64> = s.binary[at..at + total * 8]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let error_of = |level: u8, x: u32, y: u32| {
        let before: usize = (0..level).map(|l| 1usize << (2 * l)).sum();
        errors[before + morton(x, y)]
    };
    assert_eq!(
        tileset["schema"]["classes"]["tile"]["properties"]["geometricError"]["semantic"],
        "TILE_GEOMETRIC_ERROR"
    );
    assert!(errors[leaf_offset..].iter().all(|e| *e == 0.0));
    for level in 1..levels {
        for y in 0..1u32 << level {
            for x in 0..1u32 << level {
                assert!(error_of(level - 1, x / 2, y / 2) >= error_of(level, x, y));
            }
        }
    }
    assert!(error_of(0, 0, 0) > 0.0);
    // The tileset's root error is larger, so clients always refine into the tree.
    assert!(root["geometricError"].as_f64().unwrap() > error_of(0, 0, 0));

    // The explicit tileset (the default) writes the same tree out: every tile with the same
    // region and error as its metadata here, the same content, four children above the leaves.
    let explicit = get(&app, &over_extent("")).await.json();
    assert!(explicit["root"]["implicitTiling"].is_null());
    assert_eq!(explicit["root"]["refine"], "REPLACE");
    assert_eq!(
        explicit["schema"]["classes"]["building"],
        tileset["schema"]["classes"]["building"]
    );
    let mut stack = vec![(&explicit["root"], 0u8, 0u32, 0u32)];
    let mut seen = 0;
    while let Some((tile, level, x, y)) = stack.pop() {
        seen += 1;
        let want = content_uri
            .replace("{level}", &level.to_string())
            .replace("{x}", &x.to_string())
            .replace("{y}", &y.to_string());
        assert_eq!(tile["content"]["uri"], want.as_str());
        let r: Vec<f64> = tile["boundingVolume"]["region"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(r, region_of(level, x, y), "{level}/{x}/{y}");
        assert_eq!(
            tile["geometricError"],
            error_of(level, x, y),
            "{level}/{x}/{y}"
        );
        let children = tile["children"].as_array().map_or(&[][..], |c| &c[..]);
        if level == leaf {
            assert!(children.is_empty());
        } else {
            assert_eq!(children.len(), 4);
            for (k, c) in children.iter().enumerate() {
                let (dx, dy) = ((k % 2) as u32, (k / 2) as u32);
                stack.push((c, level + 1, 2 * x + dx, 2 * y + dy));
            }
        }
    }
    assert_eq!(seen, total);
    // The tileset's root spans the heights its content does.
    assert_eq!(
        (region[4], region[5]),
        (region_of(0, 0, 0)[4], region_of(0, 0, 0)[5])
    );
    // A parent holds its children.
    for level in 1..levels {
        for y in 0..1u32 << level {
            for x in 0..1u32 << level {
                let (c, p) = (region_of(level, x, y), region_of(level - 1, x / 2, y / 2));
                assert!(
                    p[0] <= c[0]
                        && p[1] <= c[1]
                        && p[2] >= c[2]
                        && p[3] >= c[3]
                        && p[4] <= c[4]
                        && p[5] >= c[5],
                    "{level}/{x}/{y}"
                );
            }
        }
    }

    // Every tile answers with valid content (coarser above the leaves); a leaf without
    // buildings is its ground alone.
    let mut with_buildings = 0;
    let mut rows_at = vec![0usize; usize::from(levels)];
    for level in 0..levels {
        for y in 0..1u32 << level {
            for x in 0..1u32 << level {
                let uri = content_uri
                    .replace("{level}", &level.to_string())
                    .replace("{x}", &x.to_string())
                    .replace("{y}", &y.to_string());
                let c = get(&app, &format!("/3dtiles/{uri}")).await;
                assert_eq!(c.status, StatusCode::OK, "{uri}");
                // Meshopt by default: valid as sent, and valid in full once decoded.
                assert_valid_glb(&c.body);
                let decoded = common::decode::decode_meshopt(&c.body);
                assert_valid_glb(&decoded);
                // Bounded content: every vertex lies inside its tile's region, as a client
                // reads it; a leaf's heights are tight (within 1 m of its content's).
                let r = region_of(level, x, y);
                let mut heights = (f64::MAX, f64::MIN);
                for (p, material) in ecef_positions(&decoded) {
                    let (lon, lat, h) = ecef_to_geodetic(p);
                    let (lon, lat) = (lon.to_radians(), lat.to_radians());
                    assert!(
                        (r[0]..=r[2]).contains(&lon)
                            && (r[1]..=r[3]).contains(&lat)
                            && (r[4]..=r[5]).contains(&h),
                        "a {material} vertex of {uri} at {lon}, {lat}, {h} lies outside {r:?}"
                    );
                    heights = (heights.0.min(h), heights.1.max(h));
                }
                if level == leaf {
                    assert!(
                        heights.0 - r[4] < 1.0 && r[5] - heights.1 < 1.0,
                        "{uri}: {heights:?} in {r:?}"
                    );
                }
                // The buildings' rows hold exactly what the feature ids name.
                rows_at[usize::from(level)] += common::decode::feature_rows(&c.body).len();
                if level == leaf
                    && common::decode::triangles(&decoded)
                        .iter()
                        .any(|t| t.material != "ground")
                {
                    with_buildings += 1;
                }
            }
        }
    }
    assert!(
        with_buildings > 0 && with_buildings < n * n,
        "{with_buildings} of {}",
        n * n
    );
    // Every level draws every building once: coarser levels flatten roofs and never leave a
    // building out, so a block of small houses is still a block from afar.
    // 3,026 records, 7 of them outlines wholly covered by their parts (only the parts drawn).
    assert_eq!(set.records().len(), 3026);
    assert_eq!(rows_at, vec![3018; usize::from(leaf) + 1]);
    println!(
        "buildings drawn per level: {rows_at:?}; root error {} m",
        error_of(0, 0, 0)
    );
    // Below the leaves there is nothing.
    let below = content_uri
        .replace("{level}", &levels.to_string())
        .replace("{x}", "0")
        .replace("{y}", "0");
    assert_eq!(
        get(&app, &format!("/3dtiles/{below}")).await.status,
        StatusCode::NOT_FOUND
    );
}

/// Positions of a content glb (in any encoding: content is meshopt by default) mapped to ECEF
/// through its node matrix (read in f64, as 3D Tiles clients do) and the 3D Tiles y-up to z-up
/// transform, with the material of each.
fn ecef_positions(glb: &[u8]) -> Vec<([f64; 3], String)> {
    common::decode::triangles(glb)
        .into_iter()
        .flat_map(|t| {
            // y-up to z-up: (x, y, z) -> (x, -z, y).
            t.corners.map(|q| ([q[0], -q[2], q[1]], t.material.clone()))
        })
        .collect()
}

#[tokio::test]
async fn a_known_building_corner_decodes_onto_its_osm_node() {
    let db = tempfile::tempdir().unwrap();
    let app = app(&db).await;
    let tileset = get(&app, &over_extent("tiling=implicit")).await.json();
    let root = &tileset["root"];
    let levels = root["implicitTiling"]["availableLevels"].as_u64().unwrap() as u32;
    let region: Vec<f64> = root["boundingVolume"]["region"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap().to_degrees())
        .collect();
    // Way 239725761 (Erna-Scheffler-Straße 6), its first node.
    let b = read_buildings(&osm_bytes("karlsruhe-kirchfeld.osm.pbf")).unwrap();
    let record = b
        .buildings
        .iter()
        .find(|r| r.id.to_string() == "way/239725761")
        .unwrap();
    let set = BuildingSet::new(b.buildings.clone());
    let cluster = set
        .clusters()
        .iter()
        .find(|c| set.cluster_records(c).iter().any(|r| r.id == record.id))
        .unwrap();
    let (lon, lat) = cluster.representative_point();
    let n = 1u32 << (levels - 1);
    let cell = |v: f64, lo: f64, hi: f64| {
        (((v - lo) / (hi - lo) * f64::from(n)).floor() as u32).min(n - 1)
    };
    let (x, y) = (
        cell(lon, region[0], region[2]),
        cell(lat, region[1], region[3]),
    );
    let uri = root["content"]["uri"]
        .as_str()
        .unwrap()
        .replace("{level}", &(levels - 1).to_string())
        .replace("{x}", &x.to_string())
        .replace("{y}", &y.to_string());
    let glb = get(&app, &format!("/3dtiles/{uri}")).await;
    assert_eq!(glb.status, StatusCode::OK);
    let positions = ecef_positions(&glb.body);

    let node = record.outers[0].nodes[0];
    let target = geodetic_to_ecef(node.lon, node.lat, 0.0);
    // The wall vertices above that corner: closest horizontally to the node.
    let dist = |p: &[f64; 3]| {
        let (plon, plat, _) = ecef_to_geodetic(*p);
        let q = geodetic_to_ecef(plon, plat, 0.0);
        ((q[0] - target[0]).powi(2) + (q[1] - target[1]).powi(2) + (q[2] - target[2]).powi(2))
            .sqrt()
    };
    let corner: Vec<&([f64; 3], String)> = positions
        .iter()
        .filter(|(p, m)| m == "wall" && dist(p) < 0.05)
        .collect();
    let nearest = positions
        .iter()
        .map(|(p, _)| dist(p))
        .fold(f64::MAX, f64::min);
    assert!(
        !corner.is_empty(),
        "no wall vertex within 5 cm of the OSM node (the nearest is {nearest} m away)"
    );
    // Its lowest point is the floor: the lowest ground along the outline
    // (docs/method.md section 3).
    let floor = corner
        .iter()
        .map(|(p, _)| ecef_to_geodetic(*p).2)
        .fold(f64::MAX, f64::min);
    let model = common_dem_model();
    let ring: Vec<(f64, f64)> = record.outers[0]
        .nodes
        .iter()
        .map(|n| (n.lon, n.lat))
        .collect();
    let (elev_min, _) = model.height_range_along(&ring);
    assert!(
        (floor - elev_min).abs() < 0.05,
        "floor {floor}, Elev_min {elev_min}"
    );
    assert!(floor <= model.ground_height(node.lon, node.lat) + 0.05);
}

fn common_dem_model() -> citymesh_core::terrain::ElevationModel {
    let bytes = std::fs::read(dem_dir().join("N49E008.hgt")).unwrap();
    citymesh_core::terrain::ElevationModel::new(vec![std::sync::Arc::new(
        citymesh_core::terrain::HgtTile::from_bytes(49, 8, &bytes).unwrap(),
    )])
}

/// Round 3, item 5: a tree's measurement is one however many ask, and outlives a request that
/// gives up (its result is kept for the next); a tileset over more than one box may cover is
/// refused rather than listing content URIs the server refuses.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tree_measurements_are_shared_kept_and_never_list_refused_uris() {
    use clap::Parser;
    let file = common::data_dir().join("osm/karlsruhe-kirchfeld.osm.pbf");
    let dem = dem_dir();
    let state_with = |db: &tempfile::TempDir, extra: &[&str]| {
        let mut argv = vec![
            "serve".to_owned(),
            "--dem-dir".to_owned(),
            dem.to_str().unwrap().to_owned(),
            "--cache-db".to_owned(),
            db.path().join("c.sqlite").to_str().unwrap().to_owned(),
            "--osm".to_owned(),
            file.to_str().unwrap().to_owned(),
        ];
        argv.extend(extra.iter().map(|a| (*a).to_owned()));
        let args = citymesh::cli::ServeArgs::parse_from(argv);
        async move { citymesh::server::build_state(&args).await }
    };
    // Kirchfeld spans about 3.3 km²: with a limit of 1 km² its tileset would list content the
    // server refuses.
    let db = tempfile::tempdir().unwrap();
    let small_state = state_with(&db, &["--max-bbox-km2", "1"]).await.unwrap();
    let small = common::app_of(small_state.clone());
    let refused = get(&small, &over_extent("")).await;
    assert_eq!(
        refused.status,
        StatusCode::BAD_REQUEST,
        "{}",
        refused.text()
    );
    assert_eq!(refused.json()["error"], "bbox_too_large");
    // The world tileset has no such limit: it is made of bounded files whatever the area.
    common::world_ready(&small_state).await;
    let world = get(&small, "/3dtiles/tileset.json").await;
    assert_eq!(world.status, StatusCode::OK, "{}", world.text());

    // A client that gives up at once (a request it drops) and five that ask together: one
    // measurement, and each answer the same tileset.
    let db = tempfile::tempdir().unwrap();
    let state = state_with(&db, &[]).await.unwrap();
    let app = citymesh::app(state.clone());
    let uri = over_extent("roofs=osm");
    let impatient = get(&app, &uri);
    assert!(
        tokio::time::timeout(std::time::Duration::ZERO, impatient)
            .await
            .is_err()
    );
    let asks: Vec<_> = (0..5)
        .map(|_| {
            let app = app.clone();
            tokio::spawn(async move { get(&app, &over_extent("roofs=osm")).await })
        })
        .collect();
    let mut bodies = std::collections::HashSet::new();
    for ask in asks {
        let answer = ask.await.unwrap();
        assert_eq!(answer.status, StatusCode::OK, "{}", answer.text());
        bodies.insert(answer.body.clone());
    }
    assert_eq!(bodies.len(), 1);
    assert_eq!(state.tiles.regions.measurements_started(), 1);
}
