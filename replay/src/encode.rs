//! The recording as the viewer loads it: one little-endian byte buffer of
//! typed sections, gzipped and base64-encoded into the HTML, and a JSON
//! header naming each section's type, offset and length.
//!
//! Sections start at multiples of 8 bytes. A section of 2- or 4-byte numbers
//! is stored as byte planes — all first bytes, then all second bytes, … (the
//! "shuffle" of HDF5 and Blosc) — so the slowly varying high bytes form long
//! runs that deflate compresses well; the viewer interleaves them back.
//!
//! Positions are stored as the per-fish difference to the previous frame
//! (wrapping u16; frame 0 holds the values themselves): a fish moves a few
//! centimetres a frame, so most differences are small. The reward terms are
//! stored term by term (`[term][frame][fish]`), so the mostly-zero terms
//! (boundary collision, chase) are long runs of zeros.
//!
//! For coho_default (1,000 fish, 60 s at 5 frames/s) this took the gzipped
//! recording from 4.9 MB (frame-major, interleaved bytes, 0.13 mm and
//! 0.005° steps) to 4.0 MB.

use crate::recording::Recording;
use base64::Engine;
use deepfoids_env::N_TERMS;
use flate2::Compression;
use flate2::write::GzEncoder;
use serde::Serialize;
use std::io::Write;

/// Bumped when the sections change; the viewer refuses other versions.
pub const FORMAT_VERSION: u32 = 1;

/// Element type of a section.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    U8,
    U16,
    I16,
    U32,
    F32,
}

/// Where a section lies in the buffer.
#[derive(Clone, Debug, Serialize)]
pub struct Section {
    pub name: &'static str,
    #[serde(rename = "type")]
    pub kind: Kind,
    /// Byte offset (a multiple of 8).
    pub offset: usize,
    /// Number of elements.
    pub length: usize,
}

/// The buffer and its table of sections.
#[derive(Clone, Debug)]
pub struct Encoded {
    pub bytes: Vec<u8>,
    pub sections: Vec<Section>,
}

/// A number a section holds.
trait Element: Copy {
    const KIND: Kind;
    const SIZE: usize;
    fn put(self, out: &mut Vec<u8>);
}

macro_rules! element {
    ($t:ty, $k:ident) => {
        impl Element for $t {
            const KIND: Kind = Kind::$k;
            const SIZE: usize = std::mem::size_of::<$t>();
            fn put(self, out: &mut Vec<u8>) {
                out.extend(self.to_le_bytes());
            }
        }
    };
}
element!(u8, U8);
element!(u16, U16);
element!(i16, I16);
element!(u32, U32);
element!(f32, F32);

#[derive(Default)]
struct Writer {
    bytes: Vec<u8>,
    sections: Vec<Section>,
}

impl Writer {
    fn section<T: Element>(&mut self, name: &'static str, values: &[T]) {
        while !self.bytes.len().is_multiple_of(8) {
            self.bytes.push(0);
        }
        self.sections.push(Section {
            name,
            kind: T::KIND,
            offset: self.bytes.len(),
            length: values.len(),
        });
        let mut raw = Vec::with_capacity(values.len() * T::SIZE);
        values.iter().for_each(|x| x.put(&mut raw));
        self.bytes.extend(byte_planes(&raw, T::SIZE));
    }
}

/// `raw` (elements of `size` bytes, in order) as byte planes.
pub fn byte_planes(raw: &[u8], size: usize) -> Vec<u8> {
    transpose(raw, size)
}

/// `[frame][fish][term]` → `[term][frame][fish]`.
pub fn term_major(terms: &[u16]) -> Vec<u16> {
    transpose(terms, N_TERMS)
}

/// Rows of `width` values, `[row][column]`, as `[column][row]`.
fn transpose<T: Copy + Default>(values: &[T], width: usize) -> Vec<T> {
    let n = values.len() / width;
    let mut out = vec![T::default(); values.len()];
    for (i, row) in values.chunks_exact(width).enumerate() {
        for (j, &v) in row.iter().enumerate() {
            out[j * n + i] = v;
        }
    }
    out
}

/// Frame-to-frame differences of the quantised positions (wrapping), per fish and axis.
pub fn position_deltas(position: &[u16], fish: usize) -> Vec<u16> {
    let row = 3 * fish;
    let mut out = position.to_vec();
    for k in (row..position.len()).rev() {
        out[k] = position[k].wrapping_sub(position[k - row]);
    }
    out
}

/// Lay out `rec`'s arrays as sections.
pub fn encode(rec: &Recording) -> Encoded {
    let mut w = Writer::default();
    let dominant: Vec<u8> = rec.dominant.iter().map(|&d| d as u8).collect();
    let pairs: Vec<u32> = rec.chase_pairs.iter().flatten().copied().collect();
    w.section("bl", &rec.bl);
    w.section("behaviour", &rec.behaviour);
    w.section("dominant", &dominant);
    w.section("times", &rec.times);
    w.section("position_delta", &position_deltas(&rec.position, rec.fish));
    w.section("yaw", &rec.yaw);
    w.section("pitch", &rec.pitch);
    w.section("speed", &rec.speed);
    w.section("flags", &rec.flags);
    w.section("terms", &term_major(&rec.terms));
    w.section("chase_count", &rec.chase_count);
    w.section("chase_pairs", &pairs);
    w.section("curve_t", &rec.curves.t);
    w.section("curve_p", &rec.curves.p);
    w.section("curve_m", &rec.curves.m);
    w.section("curve_state", &rec.curves.state);
    Encoded {
        bytes: w.bytes,
        sections: w.sections,
    }
}

/// gzip at level 9.
pub fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut gz = GzEncoder::new(Vec::with_capacity(bytes.len() / 3), Compression::best());
    gz.write_all(bytes).expect("writing to memory cannot fail");
    gz.finish().expect("writing to memory cannot fail")
}

/// Base64, standard alphabet, padded: how the HTML carries bytes.
pub fn base64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// gzip, then base64.
pub fn gzip_base64(bytes: &[u8]) -> String {
    base64(&gzip(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;
    use base64::Engine;
    use flate2::read::GzDecoder;
    use std::io::Read;

    /// Two fish, two frames: frame 1 holds the differences, wrapping below zero.
    #[test]
    fn position_deltas_wrap() {
        let pos = [10, 20, 30, 65535, 0, 5, 12, 19, 30, 0, 65535, 5];
        assert_eq!(
            position_deltas(&pos, 2),
            vec![10, 20, 30, 65535, 0, 5, 2, 65535, 0, 1, 65535, 0]
        );
    }

    /// u16 0x0201, 0x0403 little-endian: bytes 01 02 03 04 → planes 01 03 | 02 04.
    #[test]
    fn byte_planes_split_low_and_high_bytes() {
        assert_eq!(byte_planes(&[1, 2, 3, 4], 2), vec![1, 3, 2, 4]);
        assert_eq!(
            byte_planes(&[1, 2, 3, 4, 5, 6, 7, 8], 4),
            vec![1, 5, 2, 6, 3, 7, 4, 8]
        );
        assert_eq!(byte_planes(&[9, 8, 7], 1), vec![9, 8, 7]);
    }

    /// Two fish-frames of 7 terms: term j of fish-frame k lands at j · 2 + k.
    #[test]
    fn terms_are_stored_term_by_term() {
        let t: Vec<u16> = (0..14).collect();
        assert_eq!(
            term_major(&t),
            vec![0, 7, 1, 8, 2, 9, 3, 10, 4, 11, 5, 12, 6, 13]
        );
    }

    #[test]
    fn gzip_base64_round_trips() {
        let data: Vec<u8> = (0..5000u32).map(|i| (i % 7) as u8).collect();
        let b64 = gzip_base64(&data);
        let zipped = base64::engine::general_purpose::STANDARD
            .decode(&b64)
            .unwrap();
        assert!(zipped.len() < 200, "{} bytes", zipped.len());
        let mut back = vec![];
        GzDecoder::new(&zipped[..]).read_to_end(&mut back).unwrap();
        assert_eq!(back, data);
    }
}
