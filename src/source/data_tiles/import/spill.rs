//! Building records on their way to their data tiles: a tile is complete only when every file
//! has been read (a building anywhere in a file may overlap it), so each record is written, packed,
//! to a temporary bucket file chosen by its data tile; at the end the buckets are read back one
//! at a time, each split further while it is larger than the memory it may take, and grouped
//! into data tiles. Memory is the buckets' write buffers and one bucket's records.

use citymesh_core::geo::TileCoord;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Buckets a spill starts with (each split into [`SPLIT`] when too large to read at once).
const BUCKETS: usize = 64;
const SPLIT: usize = 16;
const WRITE_BUFFER: usize = 64 << 10;
/// Splits at most this deep (16^7 parts of a bucket: a bucket of 4 PB parts into 16 MB).
const MAX_DEPTH: u32 = 8;

/// Why records could not be spilled or read back.
#[derive(Debug, thiserror::Error)]
#[error("cannot keep records in temporary files under {dir}: {source}")]
pub struct SpillError {
    dir: String,
    source: std::io::Error,
}

/// One spilled record: which tile, whether this is the tile that counts the building (each is
/// stored with every tile it overlaps, counted once), and the packed record.
pub struct Spilled {
    pub home: bool,
    pub bytes: Vec<u8>,
}

pub struct TileSpill {
    dir: PathBuf,
    buckets: Vec<BufWriter<File>>,
    /// Bytes written, over all buckets.
    pub bytes: u64,
}

fn bucket_of(t: &TileCoord, depth: u32, n: usize) -> usize {
    let key = (u64::from(t.x) << 32 | u64::from(t.y)) ^ u64::from(depth).rotate_left(61);
    (xxhash_rust::xxh3::xxh3_64(&key.to_le_bytes()) as usize) % n
}

fn write_entry(
    out: &mut impl Write,
    t: &TileCoord,
    home: bool,
    bytes: &[u8],
) -> std::io::Result<()> {
    let mut head = [0u8; 14];
    head[0] = t.z;
    head[1] = u8::from(home);
    head[2..6].copy_from_slice(&t.x.to_le_bytes());
    head[6..10].copy_from_slice(&t.y.to_le_bytes());
    head[10..14].copy_from_slice(&(bytes.len() as u32).to_le_bytes());
    out.write_all(&head)?;
    out.write_all(bytes)
}

/// The next entry of a bucket, `None` at its end.
fn read_entry(input: &mut impl Read) -> std::io::Result<Option<(TileCoord, Spilled)>> {
    let mut head = [0u8; 14];
    match input.read_exact(&mut head) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(e),
    }
    let word = |at: usize| {
        let mut b = [0u8; 4];
        b.copy_from_slice(&head[at..at + 4]);
        u32::from_le_bytes(b)
    };
    let t = TileCoord {
        z: head[0],
        x: word(2),
        y: word(6),
    };
    let mut bytes = vec![0u8; word(10) as usize];
    input.read_exact(&mut bytes)?;
    Ok(Some((
        t,
        Spilled {
            home: head[1] != 0,
            bytes,
        },
    )))
}

impl TileSpill {
    pub fn create(dir: &Path) -> Result<Self, SpillError> {
        let err = |source| SpillError {
            dir: dir.display().to_string(),
            source,
        };
        let buckets = (0..BUCKETS)
            .map(|_| tempfile::tempfile_in(dir).map(|f| BufWriter::with_capacity(WRITE_BUFFER, f)))
            .collect::<Result<_, _>>()
            .map_err(err)?;
        Ok(Self {
            dir: dir.to_owned(),
            buckets,
            bytes: 0,
        })
    }

    fn error(&self, source: std::io::Error) -> SpillError {
        SpillError {
            dir: self.dir.display().to_string(),
            source,
        }
    }

    /// Spills a packed record for data tile `t`.
    pub fn push(&mut self, t: &TileCoord, home: bool, bytes: &[u8]) -> Result<(), SpillError> {
        let n = self.buckets.len();
        let out = &mut self.buckets[bucket_of(t, 0, n)];
        write_entry(out, t, home, bytes).map_err(|e| self.error(e))?;
        self.bytes += 14 + bytes.len() as u64;
        Ok(())
    }

    /// Reads the records back, one data tile at a time in no particular order, holding at most
    /// about `max_bytes` of them at once (or one data tile, if a single one is larger).
    pub fn drain(
        self,
        max_bytes: u64,
        mut each: impl FnMut(TileCoord, Vec<Spilled>) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let dir = self.dir.clone();
        let err = |source| SpillError {
            dir: dir.display().to_string(),
            source,
        };
        for bucket in self.buckets {
            let file = bucket.into_inner().map_err(|e| err(e.into_error()))?;
            drain_file(file, 1, max_bytes, &dir, &mut each)?;
        }
        Ok(())
    }
}

fn drain_file(
    mut file: File,
    depth: u32,
    max_bytes: u64,
    dir: &Path,
    each: &mut impl FnMut(TileCoord, Vec<Spilled>) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let err = |source| SpillError {
        dir: dir.display().to_string(),
        source,
    };
    let size = file.seek(SeekFrom::End(0)).map_err(err)?;
    file.seek(SeekFrom::Start(0)).map_err(err)?;
    let mut input = BufReader::with_capacity(WRITE_BUFFER, file);
    // A bucket too large to hold is split by another hash, until each part fits (one tile's
    // records always land in one part: then it is read whole).
    if size > max_bytes && depth < MAX_DEPTH {
        let mut parts = (0..SPLIT)
            .map(|_| tempfile::tempfile_in(dir).map(|f| BufWriter::with_capacity(WRITE_BUFFER, f)))
            .collect::<Result<Vec<_>, _>>()
            .map_err(err)?;
        while let Some((t, s)) = read_entry(&mut input).map_err(err)? {
            write_entry(
                &mut parts[bucket_of(&t, depth, SPLIT)],
                &t,
                s.home,
                &s.bytes,
            )
            .map_err(err)?;
        }
        drop(input);
        for part in parts {
            let file = part.into_inner().map_err(|e| err(e.into_error()))?;
            // Everything in one part is one tile (or tiles no hash tells apart): read it whole.
            let whole = file.metadata().map_err(err)?.len() == size;
            let depth = if whole { MAX_DEPTH } else { depth + 1 };
            drain_file(file, depth, max_bytes, dir, each)?;
        }
        return Ok(());
    }
    let mut tiles: BTreeMap<TileCoord, Vec<Spilled>> = BTreeMap::new();
    while let Some((t, s)) = read_entry(&mut input).map_err(err)? {
        tiles.entry(t).or_default().push(s);
    }
    for (t, records) in tiles {
        each(t, records)?;
    }
    Ok(())
}
