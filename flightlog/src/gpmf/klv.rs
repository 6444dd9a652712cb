//! GPMF's key-length-value records (GoPro's format, documented in
//! `gopro/gpmf-parser`): a four-character key, a type, a structure size and
//! a repeat count, the value padded to 4 bytes. `DEVC` nests `STRM`s; in a
//! stream, `SCAL` divides the values after it, `TYPE` spells the fields
//! of a `?` structure and `MTRX` turns the sensor's axes into the camera's
//! (as GoPro's parser does, so an IMU reads alike on every model).

use crate::LogError;

/// Keys that describe a stream rather than measure anything.
const DESCRIPTIVE: &[&[u8; 4]] = &[
    b"DVID", b"DVNM", b"TICK", b"TOCK", b"TSMP", b"STNM", b"SIUN", b"UNIT", b"SCAL", b"TYPE",
    b"TMPC", b"EMPT", b"ORIN", b"ORIO", b"MTRX", b"STMP", b"RMRK", b"TIMO", b"QUAN", b"VERS",
    b"FWVS",
];

/// One record's header and value.
#[derive(Debug, Clone, Copy)]
pub struct Record<'a> {
    pub key: [u8; 4],
    pub kind: u8,
    pub size: usize,
    pub repeat: usize,
    pub value: &'a [u8],
}

impl Record<'_> {
    pub fn key_str(&self) -> String {
        String::from_utf8_lossy(&self.key).into_owned()
    }

    fn text(&self) -> String {
        String::from_utf8_lossy(self.value)
            .trim_end_matches('\0')
            .trim()
            .to_owned()
    }
}

/// The records of one level, refusing a length that runs past its parent.
pub fn records(bytes: &[u8]) -> Result<Vec<Record<'_>>, LogError> {
    let mut out = Vec::new();
    let mut at = 0usize;
    while at + 8 <= bytes.len() {
        let h = &bytes[at..at + 8];
        let key = [h[0], h[1], h[2], h[3]];
        if key == [0; 4] {
            break; // padding at the end of a payload
        }
        let (kind, size) = (h[4], usize::from(h[5]));
        let repeat = usize::from(u16::from_be_bytes([h[6], h[7]]));
        let len = size * repeat;
        let value = bytes.get(at + 8..at + 8 + len).ok_or_else(|| {
            LogError::bare(format!(
                "GPMF: '{}' at byte {at} holds {len} bytes, past the end of its parent ({} bytes)",
                String::from_utf8_lossy(&key),
                bytes.len()
            ))
        })?;
        out.push(Record {
            key,
            kind,
            size,
            repeat,
            value,
        });
        at += 8 + len.div_ceil(4) * 4;
    }
    Ok(out)
}

/// Bytes per value of a GPMF type; `None` for the types that are not numbers.
fn width(kind: u8) -> Option<usize> {
    Some(match kind {
        b'b' | b'B' => 1,
        b's' | b'S' => 2,
        b'l' | b'L' | b'f' | b'q' => 4,
        b'j' | b'J' | b'd' | b'Q' => 8,
        _ => return None,
    })
}

fn number(kind: u8, b: &[u8]) -> f64 {
    let a4 = |b: &[u8]| [b[0], b[1], b[2], b[3]];
    let a8 = |b: &[u8]| [b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]];
    match kind {
        b'b' => f64::from(b[0] as i8),
        b'B' => f64::from(b[0]),
        b's' => f64::from(i16::from_be_bytes([b[0], b[1]])),
        b'S' => f64::from(u16::from_be_bytes([b[0], b[1]])),
        b'l' => f64::from(i32::from_be_bytes(a4(b))),
        b'L' => f64::from(u32::from_be_bytes(a4(b))),
        b'f' => f64::from(f32::from_be_bytes(a4(b))),
        b'q' => f64::from(i32::from_be_bytes(a4(b))) / 65536.0,
        b'j' => i64::from_be_bytes(a8(b)) as f64,
        b'J' => u64::from_be_bytes(a8(b)) as f64,
        b'd' => f64::from_be_bytes(a8(b)),
        b'Q' => i64::from_be_bytes(a8(b)) as f64 / 4_294_967_296.0,
        _ => f64::NAN,
    }
}

/// The samples of a numeric record, one row each, divided by `scale`
/// (one value for all fields, or one per field); `fields` spells a `?`
/// record's structure. `None` for text, dates and other non-numbers.
pub fn rows(
    r: &Record<'_>,
    scale: &[f64],
    fields: Option<&str>,
) -> Result<Option<Vec<Vec<f64>>>, LogError> {
    let kinds: Vec<u8> = if r.kind == b'?' {
        let Some(fields) = fields else {
            return Err(LogError::bare(format!(
                "GPMF: '{}' is a structure but its stream has no TYPE",
                r.key_str()
            )));
        };
        if !fields.bytes().all(|k| width(k).is_some()) {
            return Ok(None);
        }
        fields.bytes().collect()
    } else {
        let Some(w) = width(r.kind) else {
            return Ok(None);
        };
        if !r.size.is_multiple_of(w) {
            return Err(LogError::bare(format!(
                "GPMF: '{}' has samples of {} bytes, not a whole number of '{}' values",
                r.key_str(),
                r.size,
                r.kind as char
            )));
        }
        vec![r.kind; r.size / w]
    };
    let row_len: usize = kinds.iter().filter_map(|&k| width(k)).sum();
    if row_len != r.size {
        return Err(LogError::bare(format!(
            "GPMF: '{}' samples are {} bytes, its TYPE spells {row_len}",
            r.key_str(),
            r.size
        )));
    }
    let mut out = Vec::with_capacity(r.repeat);
    for sample in r.value.chunks_exact(r.size.max(1)).take(r.repeat) {
        let mut at = 0;
        let row = kinds
            .iter()
            .enumerate()
            .map(|(i, &k)| {
                let w = width(k).unwrap_or(0);
                let v = number(k, &sample[at..at + w]);
                at += w;
                let s = scale.get(i).or(scale.first()).copied().unwrap_or(1.0);
                if s == 0.0 { v } else { v / s }
            })
            .collect();
        out.push(row);
    }
    Ok(Some(out))
}

/// `row = matrix * row` where the matrix is square in the row's length
/// (row-major, as `MTRX` is written).
fn turn(matrix: &[f64], row: &mut [f64]) {
    let n = row.len();
    if n == 0 || matrix.len() != n * n {
        return;
    }
    let input = row.to_vec();
    for (i, out) in row.iter_mut().enumerate() {
        *out = (0..n).map(|j| matrix[i * n + j] * input[j]).sum();
    }
}

/// One stream's measurements in one payload.
#[derive(Debug, Clone, PartialEq)]
pub struct PayloadStream {
    pub device_id: u32,
    pub device_name: String,
    pub stream_name: String,
    pub key: [u8; 4],
    pub rows: Vec<Vec<f64>>,
}

/// Every numeric measurement of a payload, stream by stream.
pub fn payload_streams(bytes: &[u8]) -> Result<Vec<PayloadStream>, LogError> {
    let mut out = Vec::new();
    for devc in records(bytes)?.iter().filter(|r| &r.key == b"DEVC") {
        let inner = records(devc.value)?;
        let device_id = inner
            .iter()
            .find(|r| &r.key == b"DVID")
            .and_then(|r| r.value.get(..4))
            .map_or(0, |b| u32::from_be_bytes([b[0], b[1], b[2], b[3]]));
        let device_name = inner
            .iter()
            .find(|r| &r.key == b"DVNM")
            .map(Record::text)
            .unwrap_or_default();
        for strm in inner.iter().filter(|r| &r.key == b"STRM") {
            let mut scale: Vec<f64> = Vec::new();
            let mut fields: Option<String> = None;
            let mut stream_name = String::new();
            let mut matrix: Vec<f64> = Vec::new();
            for r in records(strm.value)? {
                match &r.key {
                    b"MTRX" => {
                        matrix = rows(&r, &[], None)?
                            .map(|rows| rows.into_iter().flatten().collect())
                            .unwrap_or_default();
                    }
                    b"SCAL" => {
                        scale = rows(&r, &[], None)?
                            .map(|rows| rows.into_iter().flatten().collect())
                            .unwrap_or_default();
                    }
                    b"TYPE" => fields = Some(r.text()),
                    b"STNM" => stream_name = r.text(),
                    k if DESCRIPTIVE.contains(&k) || r.kind == 0 => {}
                    _ => {
                        if let Some(mut rows) =
                            rows(&r, &scale, fields.as_deref()).map_err(|e| {
                                LogError::bare(format!("{} (device {device_name:?})", e.reason))
                            })?
                        {
                            for row in &mut rows {
                                turn(&matrix, row);
                            }
                            out.push(PayloadStream {
                                device_id,
                                device_name: device_name.clone(),
                                stream_name: stream_name.clone(),
                                key: r.key,
                                rows,
                            });
                        }
                    }
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(key: &[u8; 4], kind: u8, size: u8, repeat: u16, value: &[u8]) -> Vec<u8> {
        let mut v = key.to_vec();
        v.extend([kind, size]);
        v.extend(repeat.to_be_bytes());
        v.extend(value);
        while !v.len().is_multiple_of(4) {
            v.push(0);
        }
        v
    }

    #[test]
    fn scale_applies_per_field_and_padding_is_skipped() {
        let mut strm = record(b"STNM", b'c', 1, 3, b"GPS");
        strm.extend(record(b"SCAL", b'l', 4, 2, &[0, 0, 0, 10, 0, 0, 0, 100]));
        strm.extend(record(b"GPSX", b'l', 8, 1, &[0, 0, 0, 25, 0, 0, 1, 244]));
        let devc_body = [
            record(b"DVNM", b'c', 1, 6, b"Camera"),
            record(b"STRM", 0, 1, strm.len() as u16, &strm),
        ]
        .concat();
        let payload = record(b"DEVC", 0, 1, devc_body.len() as u16, &devc_body);
        let streams = payload_streams(&payload).unwrap();
        assert_eq!(streams.len(), 1);
        assert_eq!(streams[0].device_name, "Camera");
        assert_eq!(streams[0].stream_name, "GPS");
        assert_eq!(streams[0].rows, vec![vec![2.5, 5.0]]);
    }

    #[test]
    fn a_structure_is_read_field_by_field_from_its_type() {
        let mut strm = record(b"TYPE", b'c', 1, 2, b"sf");
        let mut v = 7i16.to_be_bytes().to_vec();
        v.extend(1.5f32.to_be_bytes());
        strm.extend(record(b"ABCD", b'?', 6, 1, &v));
        let devc = record(b"STRM", 0, 1, strm.len() as u16, &strm);
        let payload = record(b"DEVC", 0, 1, devc.len() as u16, &devc);
        assert_eq!(
            payload_streams(&payload).unwrap()[0].rows,
            vec![vec![7.0, 1.5]]
        );
    }

    #[test]
    fn a_length_past_the_parent_is_refused_by_key() {
        let mut bytes = record(b"ACCL", b's', 6, 1, &[0; 6]);
        bytes[7] = 200;
        let err = records(&bytes).unwrap_err();
        assert!(err.reason.contains("'ACCL'"), "{err}");
    }
}
