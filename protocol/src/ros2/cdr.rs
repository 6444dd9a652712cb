//! Little-endian CDR, as ROS 2 and PX4 put messages on Zenoh: a 4-byte
//! encapsulation header, then the fields in order, each aligned to its size
//! counted from the end of the header.
//!
//! Two alignments exist on the wire. ROS 2's type support (Fast-CDR under
//! rmw_zenoh) writes classic CDR (XCDR1, header `00 01`): 8-byte fields on
//! 8-byte boundaries. PX4's Zenoh module reads and writes with Cyclone's
//! XCDR2 stream, where no field aligns beyond 4 bytes. A message whose
//! 8-byte field follows an odd run of small ones (PX4's `AuxGlobalPosition`)
//! is laid out differently in the two, so the writer is told which. The
//! `cdr` crate speaks XCDR1 only, hence this small codec.

/// Which CDR flavour a payload is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CdrVersion {
    /// Classic CDR, little endian (encapsulation `00 01`): ROS 2's.
    Xcdr1,
    /// Plain XCDR2, little endian (encapsulation `00 07`): 8-byte fields
    /// aligned to 4, as PX4's Zenoh module reads them.
    Xcdr2,
}

impl CdrVersion {
    fn max_align(self) -> usize {
        match self {
            Self::Xcdr1 => 8,
            Self::Xcdr2 => 4,
        }
    }

    /// The encapsulation header's representation id.
    pub fn header(self) -> [u8; 4] {
        match self {
            Self::Xcdr1 => [0x00, 0x01, 0x00, 0x00],
            Self::Xcdr2 => [0x00, 0x07, 0x00, 0x00],
        }
    }
}

/// Writes one message's payload.
pub struct CdrWriter {
    buf: Vec<u8>,
    version: CdrVersion,
}

impl CdrWriter {
    pub fn new(version: CdrVersion) -> Self {
        let mut buf = Vec::with_capacity(256);
        buf.extend_from_slice(&version.header());
        Self { buf, version }
    }

    fn align(&mut self, size: usize) {
        let align = size.min(self.version.max_align());
        let body = self.buf.len() - 4;
        let pad = (align - body % align) % align;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    pub fn i8(&mut self, v: i8) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u16(&mut self, v: u16) {
        self.align(2);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A string: its length with the terminating NUL, its bytes, the NUL.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    /// A fixed-size array of doubles (no length on the wire).
    pub fn f64s(&mut self, values: &[f64]) {
        for v in values {
            self.f64(*v);
        }
    }

    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Why a payload could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum CdrError {
    #[error("the payload is {len} bytes: too short for its 4-byte encapsulation header")]
    NoHeader { len: usize },
    #[error("encapsulation {0:#06x} is not little-endian plain CDR (00 01) or XCDR2 (00 07)")]
    Encapsulation(u16),
    #[error("the payload ends at byte {len}; field `{field}` needs {need} more")]
    Short {
        field: &'static str,
        len: usize,
        need: usize,
    },
}

/// Reads one message's payload, field by field.
pub struct CdrReader<'a> {
    body: &'a [u8],
    at: usize,
    version: CdrVersion,
}

impl<'a> CdrReader<'a> {
    /// A reader after the header. `assume` is the flavour a sender writes
    /// whatever its header says: PX4's Zenoh module labels its XCDR2 stream
    /// `00 01`; `None` trusts the header.
    pub fn new(payload: &'a [u8], assume: Option<CdrVersion>) -> Result<Self, CdrError> {
        let (header, body) = payload
            .split_first_chunk::<4>()
            .ok_or(CdrError::NoHeader { len: payload.len() })?;
        let id = u16::from_be_bytes([header[0], header[1]]);
        let labelled = match id {
            0x0001 => CdrVersion::Xcdr1,
            0x0007 => CdrVersion::Xcdr2,
            other => return Err(CdrError::Encapsulation(other)),
        };
        Ok(Self {
            body,
            at: 0,
            version: assume.unwrap_or(labelled),
        })
    }

    fn take<const N: usize>(&mut self, field: &'static str) -> Result<[u8; N], CdrError> {
        let align = N.min(self.version.max_align());
        let start = self.at.div_ceil(align) * align;
        let bytes = self.body.get(start..start + N).ok_or(CdrError::Short {
            field,
            len: self.body.len() + 4,
            need: (start + N).saturating_sub(self.body.len()),
        })?;
        self.at = start + N;
        let mut out = [0; N];
        out.copy_from_slice(bytes);
        Ok(out)
    }

    pub fn u8(&mut self, field: &'static str) -> Result<u8, CdrError> {
        Ok(self.take::<1>(field)?[0])
    }
    pub fn u64(&mut self, field: &'static str) -> Result<u64, CdrError> {
        Ok(u64::from_le_bytes(self.take(field)?))
    }
    pub fn f32(&mut self, field: &'static str) -> Result<f32, CdrError> {
        Ok(f32::from_le_bytes(self.take(field)?))
    }
    pub fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        Ok(f64::from_le_bytes(self.take(field)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn an_eight_byte_field_after_two_bytes_sits_at_8_in_xcdr1_and_at_4_in_xcdr2() {
        for (version, offset) in [(CdrVersion::Xcdr1, 8), (CdrVersion::Xcdr2, 4)] {
            let mut w = CdrWriter::new(version);
            w.u8(1);
            w.u8(2);
            w.f64(1.5);
            let bytes = w.finish();
            assert_eq!(&bytes[..4], &version.header());
            assert_eq!(bytes.len(), 4 + offset + 8, "{version:?}");
            assert_eq!(&bytes[4 + offset..], &1.5f64.to_le_bytes());
        }
    }

    #[test]
    fn a_string_carries_its_nul_and_the_next_field_realigns() {
        let mut w = CdrWriter::new(CdrVersion::Xcdr1);
        w.string("map");
        w.f64(2.0);
        let bytes = w.finish();
        assert_eq!(&bytes[4..12], &[4, 0, 0, 0, b'm', b'a', b'p', 0]);
        // Body offset 8 is already 8-aligned.
        assert_eq!(&bytes[12..], &2.0f64.to_le_bytes());
    }

    #[test]
    fn bad_payloads_are_refused_by_name() {
        assert_eq!(
            CdrReader::new(&[0, 1], None).err(),
            Some(CdrError::NoHeader { len: 2 })
        );
        assert_eq!(
            CdrReader::new(&[0, 3, 0, 0], None).err(),
            Some(CdrError::Encapsulation(3))
        );
        let mut r = CdrReader::new(&[0, 1, 0, 0, 1, 2], None).expect("header");
        assert!(matches!(
            r.u64("timestamp"),
            Err(CdrError::Short {
                field: "timestamp",
                ..
            })
        ));
    }

    proptest! {
        #[test]
        fn what_is_written_reads_back_in_either_flavour(
            small in any::<u8>(), wide in any::<u64>(), x in -1e9f64..1e9, y in -1e6f32..1e6,
            xcdr2 in any::<bool>(),
        ) {
            let version = if xcdr2 { CdrVersion::Xcdr2 } else { CdrVersion::Xcdr1 };
            let mut w = CdrWriter::new(version);
            w.u8(small);
            w.u64(wide);
            w.u8(small);
            w.f64(x);
            w.f32(y);
            w.u8(small);
            w.f64(x);
            let bytes = w.finish();
            let mut r = CdrReader::new(&bytes, None).expect("header");
            prop_assert_eq!(r.u8("a").unwrap(), small);
            prop_assert_eq!(r.u64("b").unwrap(), wide);
            prop_assert_eq!(r.u8("c").unwrap(), small);
            prop_assert_eq!(r.f64("d").unwrap(), x);
            prop_assert_eq!(r.f32("e").unwrap(), y);
            prop_assert_eq!(r.u8("f").unwrap(), small);
            prop_assert_eq!(r.f64("g").unwrap(), x);
        }
    }
}
