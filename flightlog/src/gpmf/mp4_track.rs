//! The GPMF track of an MP4: where each payload lies in the file and which
//! stretch of the video it covers. A few boxes of ISO/IEC 14496-12 read
//! directly, because the general MP4 readers refuse GoPro's own files (an
//! `avc1` entry without `avcC` in the timecode track) and do not name a
//! `gpmd` sample entry.

use std::io::{Read, Seek, SeekFrom};

use crate::LogError;

/// One GPMF payload: its bytes' place in the file and its time span,
/// seconds from the start of the video.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Payload {
    pub offset: u64,
    pub size: u32,
    pub start_s: f64,
    pub end_s: f64,
}

/// A box's four-character type, its body's offset and its body's length.
#[derive(Debug, Clone, Copy)]
struct BoxHeader {
    kind: [u8; 4],
    body: u64,
    len: u64,
}

fn bad(reason: String) -> LogError {
    LogError::bare(format!("MP4: {reason}"))
}

fn io(what: &str) -> impl Fn(std::io::Error) -> LogError + '_ {
    move |e| bad(format!("reading {what}: {e}"))
}

/// The boxes from `start` to `end`, headers only.
fn children<R: Read + Seek>(r: &mut R, start: u64, end: u64) -> Result<Vec<BoxHeader>, LogError> {
    let mut out = Vec::new();
    let mut at = start;
    while at + 8 <= end {
        r.seek(SeekFrom::Start(at)).map_err(io("a box header"))?;
        let mut h = [0u8; 8];
        r.read_exact(&mut h).map_err(io("a box header"))?;
        let size32 = u32::from_be_bytes([h[0], h[1], h[2], h[3]]);
        let kind = [h[4], h[5], h[6], h[7]];
        let (header_len, size) = match size32 {
            0 => (8, end - at),
            1 => {
                let mut l = [0u8; 8];
                r.read_exact(&mut l).map_err(io("a 64-bit box size"))?;
                (16, u64::from_be_bytes(l))
            }
            n => (8, u64::from(n)),
        };
        if size < header_len || at + size > end {
            return Err(bad(format!(
                "box '{}' at byte {at} claims {size} bytes, past its parent's end at {end}",
                String::from_utf8_lossy(&kind)
            )));
        }
        out.push(BoxHeader {
            kind,
            body: at + header_len,
            len: size - header_len,
        });
        at += size;
    }
    Ok(out)
}

fn find(boxes: &[BoxHeader], kind: &[u8; 4]) -> Option<BoxHeader> {
    boxes.iter().find(|b| &b.kind == kind).copied()
}

/// A box's body, for the small table boxes (at most 64 MiB).
fn body<R: Read + Seek>(r: &mut R, b: BoxHeader) -> Result<Vec<u8>, LogError> {
    let what = String::from_utf8_lossy(&b.kind).into_owned();
    if b.len > 64 << 20 {
        return Err(bad(format!(
            "box '{what}' is {} bytes, too big for a table",
            b.len
        )));
    }
    r.seek(SeekFrom::Start(b.body)).map_err(io(&what))?;
    let mut v = vec![0u8; b.len as usize];
    r.read_exact(&mut v).map_err(io(&what))?;
    Ok(v)
}

/// Big-endian integers of a table box, refusing a short one by name.
struct Table<'a> {
    name: &'static str,
    bytes: &'a [u8],
}

impl Table<'_> {
    fn u32(&self, at: usize) -> Result<u32, LogError> {
        self.bytes
            .get(at..at + 4)
            .map(|b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
            .ok_or_else(|| {
                bad(format!(
                    "'{}' ends at byte {} of {at}+4",
                    self.name,
                    self.bytes.len()
                ))
            })
    }
    fn u64(&self, at: usize) -> Result<u64, LogError> {
        Ok(u64::from(self.u32(at)?) << 32 | u64::from(self.u32(at + 4)?))
    }
    /// Entry count at byte 4 (after version and flags), bounded by the box's size.
    fn count(&self, entry_len: usize, header: usize) -> Result<usize, LogError> {
        let n = self.u32(4)? as usize;
        if header + n.saturating_mul(entry_len) > self.bytes.len() {
            return Err(bad(format!(
                "'{}' lists {n} entries but holds {} bytes",
                self.name,
                self.bytes.len()
            )));
        }
        Ok(n)
    }
}

/// The payloads of the file's first track whose sample entry is `gpmd`;
/// `Ok(None)` for an MP4 without one.
pub fn gpmf_payloads<R: Read + Seek>(r: &mut R) -> Result<Option<Vec<Payload>>, LogError> {
    let end = r.seek(SeekFrom::End(0)).map_err(io("the file's length"))?;
    let top = children(r, 0, end)?;
    let Some(moov) = find(&top, b"moov") else {
        return Err(bad(
            "no 'moov' box: not an MP4 or QuickTime file, or cut short".into(),
        ));
    };
    for trak in children(r, moov.body, moov.body + moov.len)?
        .into_iter()
        .filter(|b| &b.kind == b"trak")
    {
        let Some(mdia) = find(&children(r, trak.body, trak.body + trak.len)?, b"mdia") else {
            continue;
        };
        let mdia_boxes = children(r, mdia.body, mdia.body + mdia.len)?;
        let (Some(mdhd), Some(minf)) = (find(&mdia_boxes, b"mdhd"), find(&mdia_boxes, b"minf"))
        else {
            continue;
        };
        let Some(stbl) = find(&children(r, minf.body, minf.body + minf.len)?, b"stbl") else {
            continue;
        };
        let stbl_boxes = children(r, stbl.body, stbl.body + stbl.len)?;
        let Some(stsd) = find(&stbl_boxes, b"stsd") else {
            continue;
        };
        let stsd = body(r, stsd)?;
        if stsd.get(12..16) != Some(b"gpmd") {
            continue;
        }
        let mdhd = body(r, mdhd)?;
        return track_payloads(r, &mdhd, &stbl_boxes).map(Some);
    }
    Ok(None)
}

/// The sample table of the GPMF track, as payloads in time order.
fn track_payloads<R: Read + Seek>(
    r: &mut R,
    mdhd: &[u8],
    stbl: &[BoxHeader],
) -> Result<Vec<Payload>, LogError> {
    let mdhd = Table {
        name: "mdhd",
        bytes: mdhd,
    };
    let timescale = if mdhd.bytes.first() == Some(&1) {
        mdhd.u32(20)?
    } else {
        mdhd.u32(12)?
    };
    if timescale == 0 {
        return Err(bad("the GPMF track's 'mdhd' has a time scale of 0".into()));
    }
    let table = |r: &mut R, kind: &[u8; 4]| -> Result<Option<Vec<u8>>, LogError> {
        find(stbl, kind).map(|b| body(r, b)).transpose()
    };
    let need = |v: Option<Vec<u8>>, name: &str| {
        v.ok_or_else(|| bad(format!("the GPMF track has no '{name}' box")))
    };

    let stsz_bytes = need(table(r, b"stsz")?, "stsz")?;
    let stsz = Table {
        name: "stsz",
        bytes: &stsz_bytes,
    };
    let fixed = stsz.u32(4)?;
    let count = stsz.u32(8)? as usize;
    let sizes: Vec<u32> = if fixed != 0 {
        vec![fixed; count]
    } else {
        if 12 + count.saturating_mul(4) > stsz.bytes.len() {
            return Err(bad(format!(
                "'stsz' lists {count} samples but holds {} bytes",
                stsz.bytes.len()
            )));
        }
        (0..count)
            .map(|i| stsz.u32(12 + 4 * i))
            .collect::<Result<_, _>>()?
    };

    let stts_bytes = need(table(r, b"stts")?, "stts")?;
    let stts = Table {
        name: "stts",
        bytes: &stts_bytes,
    };
    let mut times = Vec::with_capacity(count + 1);
    let mut t: u64 = 0;
    for e in 0..stts.count(8, 8)? {
        let n = stts.u32(8 + 8 * e)?;
        let delta = u64::from(stts.u32(12 + 8 * e)?);
        for _ in 0..n {
            if times.len() > count {
                break;
            }
            times.push(t);
            t += delta;
        }
    }
    times.push(t);

    let chunk_offsets: Vec<u64> = if let Some(stco) = table(r, b"stco")? {
        let stco = Table {
            name: "stco",
            bytes: &stco,
        };
        (0..stco.count(4, 8)?)
            .map(|i| stco.u32(8 + 4 * i).map(u64::from))
            .collect::<Result<_, _>>()?
    } else {
        let co64 = need(table(r, b"co64")?, "stco or co64")?;
        let co64 = Table {
            name: "co64",
            bytes: &co64,
        };
        (0..co64.count(8, 8)?)
            .map(|i| co64.u64(8 + 8 * i))
            .collect::<Result<_, _>>()?
    };

    let stsc_bytes = need(table(r, b"stsc")?, "stsc")?;
    let stsc = Table {
        name: "stsc",
        bytes: &stsc_bytes,
    };
    let runs: Vec<(u32, u32)> = (0..stsc.count(12, 8)?)
        .map(|e| Ok((stsc.u32(8 + 12 * e)?, stsc.u32(12 + 12 * e)?)))
        .collect::<Result<_, LogError>>()?;

    let mut payloads = Vec::with_capacity(count);
    let mut sample = 0usize;
    for (chunk_index, &chunk_offset) in chunk_offsets.iter().enumerate() {
        let chunk_no = chunk_index as u32 + 1;
        let per_chunk = runs
            .iter()
            .take_while(|(first, _)| *first <= chunk_no)
            .last()
            .map_or(1, |(_, n)| *n);
        let mut offset = chunk_offset;
        for _ in 0..per_chunk {
            let (Some(&size), Some(&t0), Some(&t1)) =
                (sizes.get(sample), times.get(sample), times.get(sample + 1))
            else {
                break;
            };
            payloads.push(Payload {
                offset,
                size,
                start_s: t0 as f64 / f64::from(timescale),
                end_s: t1 as f64 / f64::from(timescale),
            });
            offset += u64::from(size);
            sample += 1;
        }
    }
    if payloads.len() != count {
        return Err(bad(format!(
            "the GPMF track's tables place {} of its {count} samples",
            payloads.len()
        )));
    }
    Ok(payloads)
}

/// Reads one payload's bytes.
pub fn read_payload<R: Read + Seek>(r: &mut R, p: &Payload) -> Result<Vec<u8>, LogError> {
    r.seek(SeekFrom::Start(p.offset))
        .map_err(io("a GPMF payload"))?;
    let mut v = vec![0u8; p.size as usize];
    r.read_exact(&mut v).map_err(|e| {
        bad(format!(
            "the GPMF payload at byte {} ({} bytes) is cut short: {e}",
            p.offset, p.size
        ))
    })?;
    Ok(v)
}
