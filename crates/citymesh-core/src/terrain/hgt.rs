//! SRTM HGT files: big-endian i16 samples, rows from north to south, named after the south-west
//! corner of the 1x1 degree area they cover (`N49E008.hgt`). Edge rows and columns are shared with
//! the neighbouring files.

/// The value SRTM uses for "no data".
pub const VOID: i16 = -32768;

/// Why an HGT file could not be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HgtError {
    #[error(
        "HGT data has {0} bytes; expected 2884802 (SRTM3, 1201x1201) or 25934402 (SRTM1, 3601x3601): the file is truncated or not an HGT file"
    )]
    WrongSize(usize),
    #[error("'{0}' is not an SRTM file name like N49E008.hgt")]
    BadName(String),
    #[error("cannot read the HGT data: {0}")]
    Read(String),
}

/// The sizes of the two SRTM grids, bytes.
const SRTM3_BYTES: usize = 2_884_802;
const SRTM1_BYTES: usize = 25_934_402;

/// One parsed HGT file, or a band of its rows (see [`HgtTile::read_band`]).
#[derive(Clone, PartialEq, Eq)]
pub struct HgtTile {
    south: i32,
    west: i32,
    size: usize,
    /// The file row (0 = the northern edge) of the first row held.
    first_row: usize,
    /// Row-major, first row is `first_row` (rows run north to south, as in the file).
    samples: Vec<i16>,
}

impl std::fmt::Debug for HgtTile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "HgtTile({}, {}x{})",
            hgt_name(self.south, self.west),
            self.size,
            self.size
        )
    }
}

impl HgtTile {
    /// Parses the bytes of an HGT file covering `[south, south+1] x [west, west+1]`.
    pub fn from_bytes(south: i32, west: i32, bytes: &[u8]) -> Result<Self, HgtError> {
        let size = match bytes.len() {
            SRTM3_BYTES => 1201,
            SRTM1_BYTES => 3601,
            n => return Err(HgtError::WrongSize(n)),
        };
        let samples = bytes
            .chunks_exact(2)
            .map(|b| i16::from_be_bytes([b[0], b[1]]))
            .collect();
        Ok(Self {
            south,
            west,
            size,
            first_row: 0,
            samples,
        })
    }

    /// Reads HGT data from `reader`, decoding as it goes: the bytes are never held whole (half
    /// the memory of reading the file and then parsing it). `size_hint` is the expected byte
    /// count, when known; at most an SRTM1 file's bytes are read (then it is refused), however
    /// long the stream.
    pub fn read(
        south: i32,
        west: i32,
        reader: impl std::io::Read,
        size_hint: usize,
    ) -> Result<Self, HgtError> {
        let (samples, total) = decode(reader, SRTM1_BYTES + 1, size_hint.min(SRTM1_BYTES) / 2)?;
        if total != SRTM3_BYTES && total != SRTM1_BYTES {
            return Err(HgtError::WrongSize(total));
        }
        Self::from_samples(south, west, samples)
    }

    /// Reads only the rows of an HGT file of `file_bytes` bytes that samples between latitudes
    /// `min_lat` and `max_lat` can reach (two rows of margin each side, for the 3x3 windows of
    /// ground heights): a one-off scene of a few square kilometres reads a few hundred kilobytes
    /// of a 25 MB file. Samples outside the band answer `None`, as outside the file.
    pub fn read_band(
        south: i32,
        west: i32,
        mut file: impl std::io::Read + std::io::Seek,
        file_bytes: usize,
        min_lat: f64,
        max_lat: f64,
    ) -> Result<Self, HgtError> {
        let size = match file_bytes {
            SRTM3_BYTES => 1201,
            SRTM1_BYTES => 3601,
            n => return Err(HgtError::WrongSize(n)),
        };
        let per_degree = (size - 1) as f64;
        let north = f64::from(south + 1);
        // File rows count from the northern edge.
        let row_of = |lat: f64| ((north - lat) * per_degree).clamp(0.0, per_degree);
        let first = (row_of(max_lat).floor() as usize).saturating_sub(2);
        let last = (row_of(min_lat).ceil() as usize + 2).min(size - 1);
        if min_lat
            .partial_cmp(&max_lat)
            .is_none_or(std::cmp::Ordering::is_gt)
            || first > last
        {
            return Err(HgtError::Read(format!(
                "no rows between latitudes {min_lat} and {max_lat}"
            )));
        }
        let rows = last - first + 1;
        file.seek(std::io::SeekFrom::Start((first * size * 2) as u64))
            .map_err(|e| HgtError::Read(e.to_string()))?;
        let want = rows * size * 2;
        let (samples, total) = decode(file, want, want / 2)?;
        if total != want {
            return Err(HgtError::WrongSize(first * size * 2 + total));
        }
        Ok(Self {
            south,
            west,
            size,
            first_row: first,
            samples,
        })
    }

    /// Builds a tile from samples (rows north to south); `samples.len()` must be `size * size`
    /// with `size` 1201 or 3601.
    pub fn from_samples(south: i32, west: i32, samples: Vec<i16>) -> Result<Self, HgtError> {
        match samples.len() {
            1_442_401 => Ok(Self {
                south,
                west,
                size: 1201,
                first_row: 0,
                samples,
            }),
            12_967_201 => Ok(Self {
                south,
                west,
                size: 3601,
                first_row: 0,
                samples,
            }),
            n => Err(HgtError::WrongSize(n * 2)),
        }
    }

    /// Latitude of the southern edge.
    pub fn south(&self) -> i32 {
        self.south
    }

    /// Longitude of the western edge.
    pub fn west(&self) -> i32 {
        self.west
    }

    /// Samples per row (1201 or 3601).
    pub fn size(&self) -> usize {
        self.size
    }

    /// Sample steps per degree (1200 or 3600).
    pub fn per_degree(&self) -> u32 {
        (self.size - 1) as u32
    }

    /// The raw sample `row` rows north of the southern edge and `col` columns east of the western
    /// edge, or `None` outside the file.
    #[inline]
    pub fn raw(&self, row_from_south: usize, col: usize) -> Option<i16> {
        if row_from_south >= self.size || col >= self.size {
            return None;
        }
        let row = (self.size - 1 - row_from_south).checked_sub(self.first_row)?;
        self.samples.get(row * self.size + col).copied()
    }

    /// All samples held, rows north to south (every row of the file unless it was read as a
    /// band).
    pub fn samples(&self) -> &[i16] {
        &self.samples
    }

    /// Number of void samples.
    pub fn void_count(&self) -> usize {
        self.samples.iter().filter(|&&s| s == VOID).count()
    }

    /// Memory held by the samples, for cache weighing.
    pub fn byte_size(&self) -> usize {
        self.samples.len() * 2
    }
}

/// Big-endian samples from `reader`, decoded 64 KB at a time, reading at most `limit` bytes;
/// answers them and the bytes read.
fn decode(
    reader: impl std::io::Read,
    limit: usize,
    capacity: usize,
) -> Result<(Vec<i16>, usize), HgtError> {
    use std::io::Read;
    let mut reader = reader.take(limit as u64);
    let mut samples = Vec::with_capacity(capacity);
    let mut buf = vec![0u8; 1 << 16];
    // A chunk may end between the two bytes of a sample.
    let mut high: Option<u8> = None;
    let mut total = 0;
    loop {
        let n = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(HgtError::Read(e.to_string())),
        };
        total += n;
        let mut chunk = &buf[..n];
        if let (Some(h), Some((&l, rest))) = (high, chunk.split_first()) {
            samples.push(i16::from_be_bytes([h, l]));
            chunk = rest;
        }
        let mut pairs = chunk.chunks_exact(2);
        samples.extend(pairs.by_ref().map(|b| i16::from_be_bytes([b[0], b[1]])));
        high = pairs.remainder().first().copied();
    }
    Ok((samples, total))
}

/// The conventional file stem of the tile with this south-west corner (`N49E008`).
pub fn hgt_name(south: i32, west: i32) -> String {
    format!(
        "{}{:02}{}{:03}",
        if south < 0 { 'S' } else { 'N' },
        south.unsigned_abs(),
        if west < 0 { 'W' } else { 'E' },
        west.unsigned_abs()
    )
}

/// Reads the south-west corner `(lat, lon)` from a file name such as `N49E008.hgt`,
/// `s12w077.hgt.zip` or `N49E008.SRTMGL1.hgt.gz`.
///
/// ```
/// use citymesh_core::terrain::parse_hgt_name;
/// assert_eq!(parse_hgt_name("N49E008.hgt").unwrap(), (49, 8));
/// assert_eq!(parse_hgt_name("s12w077.hgt.zip").unwrap(), (-12, -77));
/// assert!(parse_hgt_name("readme.txt").is_err());
/// ```
pub fn parse_hgt_name(name: &str) -> Result<(i32, i32), HgtError> {
    let bad = || HgtError::BadName(name.chars().take(80).collect());
    let b = name.as_bytes();
    if b.len() < 7 {
        return Err(bad());
    }
    let digits = |s: &[u8]| -> Option<i32> {
        s.iter().try_fold(0i32, |acc, &c| {
            c.is_ascii_digit().then(|| acc * 10 + i32::from(c - b'0'))
        })
    };
    let lat_sign = match b[0].to_ascii_uppercase() {
        b'N' => 1,
        b'S' => -1,
        _ => return Err(bad()),
    };
    let lon_sign = match b[3].to_ascii_uppercase() {
        b'E' => 1,
        b'W' => -1,
        _ => return Err(bad()),
    };
    let lat = digits(&b[1..3]).ok_or_else(bad)? * lat_sign;
    let lon = digits(&b[4..7]).ok_or_else(bad)? * lon_sign;
    if !(-90..90).contains(&lat) || !(-180..180).contains(&lon) {
        return Err(bad());
    }
    Ok((lat, lon))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that hands out its bytes in odd-sized pieces, as a decompressor may.
    struct Dribble<'a>(&'a [u8], usize);

    impl std::io::Read for Dribble<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.1.min(buf.len()).min(self.0.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn reading_a_stream_in_odd_pieces_equals_parsing_the_bytes() {
        let bytes: Vec<u8> = (0..SRTM3_BYTES).map(|i| (i * 7 % 251) as u8).collect();
        let parsed = HgtTile::from_bytes(49, 8, &bytes).unwrap();
        for piece in [1, 3, 4097, 1 << 16] {
            let read = HgtTile::read(49, 8, Dribble(&bytes, piece), 0).unwrap();
            assert_eq!(read, parsed, "pieces of {piece}");
        }
        assert_eq!(
            HgtTile::read(49, 8, Dribble(&bytes[..SRTM3_BYTES - 1], 999), SRTM3_BYTES),
            Err(HgtError::WrongSize(SRTM3_BYTES - 1))
        );
        // An endless stream stops one byte past the largest size.
        assert_eq!(
            HgtTile::read(49, 8, std::io::repeat(0), 0),
            Err(HgtError::WrongSize(SRTM1_BYTES + 1))
        );
    }

    #[test]
    fn a_band_of_rows_answers_as_the_whole_file_inside_and_none_outside() {
        let bytes: Vec<u8> = (0..SRTM3_BYTES).map(|i| (i * 7 % 251) as u8).collect();
        let whole = HgtTile::from_bytes(49, 8, &bytes).unwrap();
        // 49.5 to 49.75 N: file rows 300 to 600 from the north, plus two each side.
        let band = HgtTile::read_band(
            49,
            8,
            std::io::Cursor::new(&bytes),
            SRTM3_BYTES,
            49.5,
            49.75,
        )
        .unwrap();
        assert_eq!(band.samples().len(), (602 - 298 + 1) * 1201);
        for row_from_south in 0..1201 {
            let north_row = 1200 - row_from_south;
            for col in [0, 1, 600, 1200] {
                let want = if (298..=602).contains(&north_row) {
                    whole.raw(row_from_south, col)
                } else {
                    None
                };
                assert_eq!(
                    band.raw(row_from_south, col),
                    want,
                    "row {north_row} col {col}"
                );
            }
        }
        // The southern edge row, and a file of the wrong size.
        let edge = HgtTile::read_band(49, 8, std::io::Cursor::new(&bytes), SRTM3_BYTES, 49.0, 49.0)
            .unwrap();
        assert_eq!(edge.raw(0, 5), whole.raw(0, 5));
        assert_eq!(
            HgtTile::read_band(49, 8, std::io::Cursor::new(&bytes[..100]), 100, 49.0, 49.5),
            Err(HgtError::WrongSize(100))
        );
        // A file shorter than its size said.
        assert!(matches!(
            HgtTile::read_band(
                49,
                8,
                std::io::Cursor::new(&bytes[..1_000_000]),
                SRTM3_BYTES,
                49.0,
                49.1
            ),
            Err(HgtError::WrongSize(_))
        ));
    }

    #[test]
    fn refuses_truncated_bytes() {
        let bytes = vec![0u8; 2_884_800];
        assert_eq!(
            HgtTile::from_bytes(49, 8, &bytes),
            Err(HgtError::WrongSize(2_884_800))
        );
    }

    #[test]
    fn reads_big_endian_rows_from_north() {
        let mut bytes = vec![0u8; 2_884_802];
        // Last sample of the file: the south-east corner, value 0x0102 = 258.
        bytes[2_884_800] = 1;
        bytes[2_884_801] = 2;
        // First sample: the north-west corner, void.
        bytes[0] = 0x80;
        let t = HgtTile::from_bytes(49, 8, &bytes).unwrap();
        assert_eq!(t.raw(0, 1200), Some(258));
        assert_eq!(t.raw(1200, 0), Some(VOID));
        assert_eq!(t.raw(1201, 0), None);
        assert_eq!(t.void_count(), 1);
        assert_eq!(hgt_name(-12, -77), "S12W077");
    }
}
