//! The buildings of an OSM PBF file, read as a stream: memory does not grow with the file.
//!
//! A PBF file gives its nodes, then its ways, then its relations, each sorted by id (the
//! standard order; `osmium sort` makes it). Three steps use that order:
//! 1. the relations, at the end of the file, are read first, walking back from the last block
//!    until one holds none: the building multipolygons are kept (they are few), and with them
//!    the ids of their member ways;
//! 2. every node goes to the on-disk [`NodeIndexWriter`], in the file's order;
//! 3. the ways: each block is decoded on its own thread, its building ways get their nodes from
//!    the index and are assembled there, and the records reach `each` a block at a time; the
//!    member ways of step 1 are kept with their nodes.
//!
//! Then the multipolygons are assembled from the kept member ways. Every building goes through
//! [`assemble`], as when a whole file is read: the same records, skips and repairs.
//! A file out of this order is refused by the id where it goes wrong, never half read.

use super::node_index::{BlockCache, NodeIndexError, NodeIndexWriter, NodeLocations};
use citymesh_core::osm::{
    MemberKind, OsmBuildings, RawOsm, RawRelation, RawWay, Tags, assemble, building_kind,
    is_building_multipolygon, relation_members,
};
use foldhash::HashSet;
use osmpbf::{Blob, BlobDecode, BlobReader, BlobType, ByteOffset, PrimitiveBlock};
use std::collections::BTreeMap;
use std::ops::ControlFlow;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;

/// Why a PBF file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum PbfError {
    #[error("cannot read it: {0}")]
    Io(#[from] std::io::Error),
    #[error("corrupt or truncated at byte {at}: {what}")]
    Corrupt { at: u64, what: String },
    #[error(
        "not sorted: {0} (citymesh reads nodes, then ways, then relations, each by id; sort it with `osmium sort`)"
    )]
    NotSorted(String),
    #[error(transparent)]
    Nodes(#[from] NodeIndexError),
    #[error("{0}")]
    Records(String),
}

/// How the stream may use the machine.
pub struct StreamLimits {
    /// Threads decoding blocks.
    pub threads: usize,
    /// Bytes of node blocks each thread caches.
    pub cache_bytes: usize,
}

/// What a stream read, besides its buildings.
#[derive(Debug, Default)]
pub struct StreamCounts {
    pub nodes: u64,
    pub ways: u64,
    pub relations: u64,
    /// Node index blocks read from disk (the rest came from the threads' caches).
    pub node_reads: u64,
}

fn corrupt(at: Option<ByteOffset>, e: impl std::fmt::Display) -> PbfError {
    PbfError::Corrupt {
        at: at.map_or(0, |o| o.0),
        what: e.to_string(),
    }
}

/// The offset of every data block, in file order.
fn data_blocks(path: &Path) -> Result<Vec<ByteOffset>, PbfError> {
    let mut reader = BlobReader::seekable_from_path(path).map_err(|e| corrupt(None, e))?;
    let mut blocks = Vec::new();
    let mut header = false;
    while let Some(next) = reader.next_header_skip_blob() {
        let (h, at) = next.map_err(|e| corrupt(None, e))?;
        let at = at.ok_or_else(|| corrupt(None, "a block without an offset"))?;
        match h.blob_type() {
            BlobType::OsmHeader => header = true,
            BlobType::OsmData => blocks.push(at),
            BlobType::Unknown(_) => {}
        }
    }
    if !header {
        return Err(corrupt(None, "no OSMHeader block: not an OSM PBF file"));
    }
    Ok(blocks)
}

fn decode(blob: &Blob) -> Result<PrimitiveBlock, PbfError> {
    match blob.decode().map_err(|e| corrupt(blob.offset(), e))? {
        BlobDecode::OsmData(block) => Ok(block),
        _ => Err(corrupt(
            blob.offset(),
            "a data block that does not decode as one",
        )),
    }
}

fn tags<'a>(iter: impl Iterator<Item = (&'a str, &'a str)>) -> Tags {
    iter.map(|(k, v)| (k.to_owned(), v.to_owned())).collect()
}

/// What a block holds, besides what a step takes from it.
#[derive(Default, Clone, Copy)]
struct Holds {
    nodes: bool,
    ways: bool,
    relations: bool,
}

fn holds(block: &PrimitiveBlock) -> Holds {
    let mut h = Holds::default();
    for g in block.groups() {
        h.nodes |= g.nodes().next().is_some() || g.dense_nodes().next().is_some();
        h.ways |= g.ways().next().is_some();
        h.relations |= g.relations().next().is_some();
    }
    h
}

/// Step 1: the building multipolygons at the end of the file; the number of trailing blocks
/// that hold nothing else.
fn read_relations(
    path: &Path,
    blocks: &[ByteOffset],
    counts: &mut StreamCounts,
) -> Result<(Vec<RawRelation>, usize), PbfError> {
    let mut reader = BlobReader::seekable_from_path(path).map_err(|e| corrupt(None, e))?;
    let mut kept = Vec::new();
    let mut relation_only = 0;
    let mut after: Option<i64> = None;
    for at in blocks.iter().rev() {
        let blob = reader
            .blob_from_offset(*at)
            .map_err(|e| corrupt(Some(*at), e))?;
        let block = decode(&blob)?;
        let h = holds(&block);
        if !h.relations {
            break;
        }
        let mut in_block = Vec::new();
        for r in block
            .groups()
            .flat_map(|g| g.relations().collect::<Vec<_>>())
        {
            if let Some(last) = in_block.last().map(|(id, _)| *id)
                && r.id() <= last
            {
                return Err(PbfError::NotSorted(format!(
                    "relation {} after relation {last}",
                    r.id()
                )));
            }
            counts.relations += 1;
            let t = tags(r.tags());
            let kept_relation = is_building_multipolygon(&t).then(|| RawRelation {
                id: r.id(),
                members: relation_members(&r),
                tags: t,
            });
            in_block.push((r.id(), kept_relation));
        }
        if let (Some((last, _)), Some(next)) = (in_block.last(), after)
            && *last >= next
        {
            return Err(PbfError::NotSorted(format!(
                "relation {next} after relation {last}"
            )));
        }
        after = in_block.first().map(|(id, _)| *id);
        kept.extend(in_block.into_iter().rev().filter_map(|(_, r)| r));
        if h.nodes || h.ways {
            break;
        }
        relation_only += 1;
    }
    kept.reverse();
    Ok((kept, relation_only))
}

/// Decodes `blocks` on `threads` threads with `work` (each thread with its own state from
/// `init`) and hands the results to `consume` in file order, until it breaks. Bounded: at
/// most a few blocks per thread are read ahead.
fn in_order<S, T: Send>(
    path: &Path,
    blocks: &[ByteOffset],
    threads: usize,
    init: impl Fn() -> S + Sync,
    work: impl Fn(usize, &Blob, &mut S) -> Result<T, PbfError> + Sync,
    mut consume: impl FnMut(usize, T) -> Result<ControlFlow<()>, PbfError>,
) -> Result<(), PbfError> {
    let mut reader = BlobReader::seekable_from_path(path).map_err(|e| corrupt(None, e))?;
    let stop = AtomicBool::new(false);
    let (work_tx, work_rx) = sync_channel::<(usize, Blob)>(threads * 2);
    let work_rx = Mutex::new(work_rx);
    let (done_tx, done_rx) = sync_channel::<(usize, Result<T, PbfError>)>(threads);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            let done_tx = done_tx.clone();
            let (work_rx, stop, init, work) = (&work_rx, &stop, &init, &work);
            s.spawn(move || {
                let mut state = init();
                loop {
                    let job = match work_rx.lock() {
                        Ok(rx) => rx.recv(),
                        Err(_) => break,
                    };
                    let Ok((i, blob)) = job else { break };
                    if stop.load(Ordering::Relaxed) {
                        continue;
                    }
                    if done_tx.send((i, work(i, &blob, &mut state))).is_err() {
                        break;
                    }
                }
            });
        }
        let reader_done = done_tx.clone();
        drop(done_tx);
        let stop_reading = &stop;
        s.spawn(move || {
            for (i, at) in blocks.iter().enumerate() {
                if stop_reading.load(Ordering::Relaxed) {
                    break;
                }
                match reader.blob_from_offset(*at) {
                    Ok(blob) => {
                        if work_tx.send((i, blob)).is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        let _ = reader_done.send((i, Err(corrupt(Some(*at), e))));
                        break;
                    }
                }
            }
        });
        let mut pending = BTreeMap::new();
        let mut next = 0;
        let mut outcome = Ok(());
        for (i, result) in &done_rx {
            if stop.load(Ordering::Relaxed) {
                continue;
            }
            pending.insert(i, result);
            while let Some(result) = pending.remove(&next) {
                next += 1;
                let flow = result.and_then(|t| consume(next - 1, t));
                match flow {
                    Ok(ControlFlow::Continue(())) => {}
                    Ok(ControlFlow::Break(())) => stop.store(true, Ordering::Relaxed),
                    Err(e) => {
                        outcome = Err(e);
                        stop.store(true, Ordering::Relaxed);
                    }
                }
                if stop.load(Ordering::Relaxed) {
                    break;
                }
            }
        }
        outcome
    })
}

/// A member way of a building multipolygon, with its nodes' locations.
type MemberWay = (RawWay, Vec<(i64, (f64, f64))>);

/// What the ways of one block gave.
struct WayBlock<P> {
    /// The block's buildings as `prepare` made them, a batch at a time.
    buildings: Vec<P>,
    /// Member ways of building multipolygons, with their nodes' locations.
    members: Vec<MemberWay>,
    first: Option<i64>,
    last: Option<i64>,
    ways: u64,
}

/// Building ways assembled at once.
const BATCH: usize = 256;

/// A location as a PBF reader computes it from whole 1e-7 degrees (nanodegrees times 1e-9).
fn degrees(units: i32) -> f64 {
    1e-9 * (i64::from(units) * 100) as f64
}

/// The buildings of the PBF file at `path`, a block at a time: made into `P` by `prepare` on
/// the thread that decoded the block (so what waits to be consumed is small), then handed to
/// `each` in file order; `progress` gets the bytes read so far. Node locations are kept in
/// `temp_dir`.
pub fn stream<P: Send>(
    path: &Path,
    temp_dir: &Path,
    limits: &StreamLimits,
    progress: &(dyn Fn(u64) + Sync),
    prepare: &(dyn Fn(OsmBuildings) -> P + Sync),
    each: &mut dyn FnMut(P) -> Result<(), PbfError>,
) -> Result<StreamCounts, PbfError> {
    let mut counts = StreamCounts::default();
    let blocks = data_blocks(path)?;
    let (relations, relation_only) = read_relations(path, &blocks, &mut counts)?;
    let members: HashSet<i64> = relations
        .iter()
        .flat_map(|r| &r.members)
        .filter(|m| m.kind == MemberKind::Way)
        .map(|m| m.id)
        .collect();
    let offset = |i: usize| blocks.get(i).map_or(0, |o| o.0);
    let blocks = &blocks[..blocks.len() - relation_only];

    // Step 2: the nodes, up to the first block that holds anything else.
    let mut index = NodeIndexWriter::create(temp_dir)?;
    let mut first_other = blocks.len();
    in_order(
        path,
        blocks,
        limits.threads,
        || (),
        |_, blob, _| {
            let block = decode(blob)?;
            let mut nodes = Vec::new();
            for g in block.groups() {
                nodes.extend(
                    g.dense_nodes()
                        .map(|n| (n.id(), n.decimicro_lon(), n.decimicro_lat())),
                );
                nodes.extend(
                    g.nodes()
                        .map(|n| (n.id(), n.decimicro_lon(), n.decimicro_lat())),
                );
            }
            let h = holds(&block);
            Ok((nodes, h.ways || h.relations))
        },
        |i, (nodes, other)| {
            for (id, lon, lat) in nodes {
                index.push(id, lon, lat)?;
            }
            progress(offset(i));
            if other {
                first_other = i;
                return Ok(ControlFlow::Break(()));
            }
            Ok(ControlFlow::Continue(()))
        },
    )?;
    counts.nodes = index.len();
    let nodes = index.finish()?;

    // Step 3: the ways.
    let ways_from = first_other;
    let ways = &blocks[ways_from..];
    let mut kept_members: Vec<MemberWay> = Vec::new();
    let mut last_way: Option<i64> = None;
    let node_reads = Mutex::new(0u64);
    {
        let work = |i: usize, blob: &Blob, cache: &mut BlockCache| {
            way_block(&decode(blob)?, i == 0, &members, &nodes, cache, prepare)
        };
        in_order(
            path,
            ways,
            limits.threads,
            || CountedCache(BlockCache::new(limits.cache_bytes), &node_reads),
            |i, blob, cache| work(i, blob, &mut cache.0),
            |i, block| {
                if let (Some(last), Some(first)) = (last_way, block.first)
                    && first <= last
                {
                    return Err(PbfError::NotSorted(format!("way {first} after way {last}")));
                }
                last_way = block.last.or(last_way);
                counts.ways += block.ways;
                kept_members.extend(block.members);
                progress(offset(ways_from + i));
                for batch in block.buildings {
                    each(batch)?;
                }
                Ok(ControlFlow::Continue(()))
            },
        )?;
    }
    counts.node_reads = node_reads.lock().map_or(0, |n| *n);

    // The multipolygons, with their member ways (building ways among them are assembled here,
    // where the relations that may draw them are).
    let mut raw = RawOsm {
        relations,
        ..RawOsm::default()
    };
    for (way, located) in kept_members {
        raw.nodes.extend(located);
        raw.ways.push(way);
    }
    each(prepare(assemble(raw)))?;
    Ok(counts)
}

/// A thread's cache, whose disk reads are added to a shared count when the thread ends.
struct CountedCache<'a>(BlockCache, &'a Mutex<u64>);

impl Drop for CountedCache<'_> {
    fn drop(&mut self) {
        if let Ok(mut n) = self.1.lock() {
            *n += self.0.reads;
        }
    }
}

/// The building ways of one block, assembled; member ways kept with their nodes.
fn way_block<P>(
    block: &PrimitiveBlock,
    nodes_allowed: bool,
    members: &HashSet<i64>,
    nodes: &NodeLocations,
    cache: &mut BlockCache,
    prepare: &(dyn Fn(OsmBuildings) -> P + Sync),
) -> Result<WayBlock<P>, PbfError> {
    let h = holds(block);
    if h.relations {
        return Err(PbfError::NotSorted(
            "relations before the last way".to_owned(),
        ));
    }
    if h.nodes && !nodes_allowed {
        return Err(PbfError::NotSorted("nodes after ways".to_owned()));
    }
    let mut raw = RawOsm::default();
    let mut out = WayBlock {
        buildings: Vec::new(),
        members: Vec::new(),
        first: None,
        last: None,
        ways: 0,
    };
    let mut locate =
        |refs: &[i64], into: &mut dyn FnMut(i64, (f64, f64))| -> Result<(), PbfError> {
            for &id in refs {
                if let Some((lon, lat)) = nodes.get(id, cache)? {
                    into(id, (degrees(lon), degrees(lat)));
                }
            }
            Ok(())
        };
    for g in block.groups() {
        for w in g.ways() {
            let id = w.id();
            if let Some(last) = out.last
                && id <= last
            {
                return Err(PbfError::NotSorted(format!("way {id} after way {last}")));
            }
            out.first.get_or_insert(id);
            out.last = Some(id);
            out.ways += 1;
            let member = members.contains(&id);
            let t = tags(w.tags());
            let building = building_kind(&t).is_some();
            if !(building || member) {
                continue;
            }
            let refs: Vec<i64> = w.refs().collect();
            let way = RawWay {
                id,
                refs,
                geometry: None,
                // A member way's tags only matter when it is a building itself.
                tags: if building { t } else { Tags::new() },
            };
            if member {
                let mut located = Vec::with_capacity(way.refs.len());
                locate(&way.refs, &mut |id, p| located.push((id, p)))?;
                out.members.push((way, located));
            } else {
                locate(&way.refs, &mut |id, p| {
                    raw.nodes.insert(id, p);
                })?;
                raw.ways.push(way);
                // Assembled a batch at a time: records are large, what `prepare` makes small.
                if raw.ways.len() >= BATCH {
                    out.buildings
                        .push(prepare(assemble(std::mem::take(&mut raw))));
                }
            }
        }
    }
    out.buildings.push(prepare(assemble(raw)));
    Ok(out)
}
