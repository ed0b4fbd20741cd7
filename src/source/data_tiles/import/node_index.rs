//! Node locations of an OSM PBF file, kept on disk while the file's ways are read: a sorted
//! array of 16-byte entries (id, longitude and latitude in whole 1e-7 degrees), written once in
//! the order the file gives its nodes, then looked up by binary search.
//!
//! Why this structure: a PBF file gives its nodes sorted by id, so appending them is the whole
//! of the sorting; ids are sparse in a range of 1.3e10 (a dense array indexed by id would be
//! 100 GB of file for an extract), and the ways that follow use nodes with nearby ids, so the
//! 4 KB blocks a lookup reads repeat and a small cache of blocks answers most lookups. Memory
//! is the cache (a budget's share) and one 8-byte first id per block of 256 nodes (0.03 bytes
//! per node: 3 MB for 100 million nodes); the file is 16 bytes per node, read through the page
//! cache (which the kernel may drop, and does not count as the process's memory).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::os::unix::fs::FileExt;
use std::path::Path;

/// Bytes of one entry: id (i64), longitude and latitude (i32 each), little-endian.
const ENTRY: usize = 16;
/// Entries per block (one 4 KB page).
const PER_BLOCK: usize = 256;
const BLOCK: usize = ENTRY * PER_BLOCK;

/// Why nodes could not be indexed or looked up.
#[derive(Debug, thiserror::Error)]
pub enum NodeIndexError {
    #[error(
        "node {id} comes after node {previous}: the file is not sorted by id (sort it with `osmium sort`)"
    )]
    OutOfOrder { id: i64, previous: i64 },
    #[error("cannot write the node index in {dir}: {source}")]
    Write { dir: String, source: std::io::Error },
    #[error("cannot read the node index: {0}")]
    Read(std::io::Error),
}

/// Node locations being appended, in id order.
pub struct NodeIndexWriter {
    out: BufWriter<File>,
    dir: String,
    /// The first id of each block.
    firsts: Vec<i64>,
    count: u64,
    last: Option<i64>,
}

impl NodeIndexWriter {
    /// A new index in a temporary file under `dir` (removed when the index is dropped).
    pub fn create(dir: &Path) -> Result<Self, NodeIndexError> {
        let name = dir.display().to_string();
        let file = tempfile::tempfile_in(dir).map_err(|source| NodeIndexError::Write {
            dir: name.clone(),
            source,
        })?;
        Ok(Self {
            out: BufWriter::with_capacity(1 << 20, file),
            dir: name,
            firsts: Vec::new(),
            count: 0,
            last: None,
        })
    }

    /// Appends a node; ids must increase.
    pub fn push(&mut self, id: i64, lon: i32, lat: i32) -> Result<(), NodeIndexError> {
        if let Some(previous) = self.last
            && id <= previous
        {
            return Err(NodeIndexError::OutOfOrder { id, previous });
        }
        self.last = Some(id);
        if self.count.is_multiple_of(PER_BLOCK as u64) {
            self.firsts.push(id);
        }
        let mut entry = [0u8; ENTRY];
        entry[..8].copy_from_slice(&id.to_le_bytes());
        entry[8..12].copy_from_slice(&lon.to_le_bytes());
        entry[12..].copy_from_slice(&lat.to_le_bytes());
        self.out
            .write_all(&entry)
            .map_err(|source| NodeIndexError::Write {
                dir: self.dir.clone(),
                source,
            })?;
        self.count += 1;
        Ok(())
    }

    /// Nodes appended so far.
    pub fn len(&self) -> u64 {
        self.count
    }

    /// The index, ready for lookups.
    pub fn finish(self) -> Result<NodeLocations, NodeIndexError> {
        let dir = self.dir;
        let file = self.out.into_inner().map_err(|e| NodeIndexError::Write {
            dir: dir.clone(),
            source: e.into_error(),
        })?;
        Ok(NodeLocations {
            file,
            firsts: self.firsts,
            count: self.count,
        })
    }
}

/// Node locations, looked up by id from any thread (each with its own [`BlockCache`]).
pub struct NodeLocations {
    file: File,
    firsts: Vec<i64>,
    count: u64,
}

/// Recently read blocks of a [`NodeLocations`], one cache per thread: a block goes in the slot
/// its number picks, replacing what was there.
pub struct BlockCache {
    slots: Vec<Option<(usize, Box<[u8; BLOCK]>)>>,
    pub reads: u64,
}

impl BlockCache {
    /// A cache of at most `bytes` (at least one block).
    pub fn new(bytes: usize) -> Self {
        Self {
            slots: (0..(bytes / BLOCK).max(1)).map(|_| None).collect(),
            reads: 0,
        }
    }
}

fn entry_id(block: &[u8], i: usize) -> i64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&block[i * ENTRY..i * ENTRY + 8]);
    i64::from_le_bytes(b)
}

fn entry_i32(block: &[u8], at: usize) -> i32 {
    let mut b = [0u8; 4];
    b.copy_from_slice(&block[at..at + 4]);
    i32::from_le_bytes(b)
}

impl NodeLocations {
    /// The location of node `id` (longitude and latitude in whole 1e-7 degrees), if the file
    /// has it.
    pub fn get(
        &self,
        id: i64,
        cache: &mut BlockCache,
    ) -> Result<Option<(i32, i32)>, NodeIndexError> {
        let Some(block) = self.firsts.partition_point(|f| *f <= id).checked_sub(1) else {
            return Ok(None);
        };
        let n = (self.count as usize - block * PER_BLOCK).min(PER_BLOCK);
        let slot = block % cache.slots.len();
        if !matches!(&cache.slots[slot], Some((b, _)) if *b == block) {
            let mut bytes = Box::new([0u8; BLOCK]);
            self.file
                .read_exact_at(&mut bytes[..n * ENTRY], (block * BLOCK) as u64)
                .map_err(NodeIndexError::Read)?;
            cache.reads += 1;
            cache.slots[slot] = Some((block, bytes));
        }
        let Some((_, bytes)) = &cache.slots[slot] else {
            return Ok(None);
        };
        let (mut lo, mut hi) = (0, n);
        while lo < hi {
            let mid = (lo + hi) / 2;
            match entry_id(&bytes[..], mid).cmp(&id) {
                std::cmp::Ordering::Less => lo = mid + 1,
                std::cmp::Ordering::Greater => hi = mid,
                std::cmp::Ordering::Equal => {
                    let at = mid * ENTRY;
                    return Ok(Some((
                        entry_i32(&bytes[..], at + 8),
                        entry_i32(&bytes[..], at + 12),
                    )));
                }
            }
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn every_node_is_found_and_no_other(
            gaps in proptest::collection::vec(1i64..5_000_000_000, 1..2_000),
            probes in proptest::collection::vec(any::<i64>(), 0..200),
            cache_blocks in 1usize..4,
        ) {
            let dir = tempfile::tempdir().unwrap();
            let mut w = NodeIndexWriter::create(dir.path()).unwrap();
            let mut ids = Vec::new();
            let mut id = -1_000_000i64;
            for (i, g) in gaps.iter().enumerate() {
                id = id.saturating_add(*g);
                if ids.last() == Some(&id) {
                    break;
                }
                w.push(id, i as i32, -(i as i32)).unwrap();
                ids.push(id);
            }
            let nodes = w.finish().unwrap();
            prop_assert_eq!(nodes.count, ids.len() as u64);
            let mut cache = BlockCache::new(cache_blocks * BLOCK);
            for (i, id) in ids.iter().enumerate() {
                prop_assert_eq!(nodes.get(*id, &mut cache).unwrap(), Some((i as i32, -(i as i32))));
            }
            for p in probes {
                let want = ids.iter().position(|i| *i == p).map(|i| (i as i32, -(i as i32)));
                prop_assert_eq!(nodes.get(p, &mut cache).unwrap(), want);
            }
        }
    }

    #[test]
    fn a_node_out_of_order_is_refused_by_id() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = NodeIndexWriter::create(dir.path()).unwrap();
        w.push(10, 0, 0).unwrap();
        let e = w.push(7, 0, 0).unwrap_err().to_string();
        assert!(
            e.contains("node 7 comes after node 10") && e.contains("osmium sort"),
            "{e}"
        );
        assert!(w.push(10, 0, 0).is_err(), "a repeated id too");
    }
}
