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

/// One parsed HGT file.
#[derive(Clone, PartialEq, Eq)]
pub struct HgtTile {
    south: i32,
    west: i32,
    size: usize,
    /// Row-major, first row is the northern edge (as in the file).
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
        use std::io::Read;
        let mut reader = reader.take(SRTM1_BYTES as u64 + 1);
        let mut samples = Vec::with_capacity(size_hint.min(SRTM1_BYTES) / 2);
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
        if total != SRTM3_BYTES && total != SRTM1_BYTES {
            return Err(HgtError::WrongSize(total));
        }
        Self::from_samples(south, west, samples)
    }

    /// Builds a tile from samples (rows north to south); `samples.len()` must be `size * size`
    /// with `size` 1201 or 3601.
    pub fn from_samples(south: i32, west: i32, samples: Vec<i16>) -> Result<Self, HgtError> {
        match samples.len() {
            1_442_401 => Ok(Self {
                south,
                west,
                size: 1201,
                samples,
            }),
            12_967_201 => Ok(Self {
                south,
                west,
                size: 3601,
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
        Some(self.samples[(self.size - 1 - row_from_south) * self.size + col])
    }

    /// All samples, rows north to south.
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
