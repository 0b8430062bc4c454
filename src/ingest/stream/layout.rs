//! A stream file's layout from its header: WAV/RF64, NumPy `.npy`, or a raw binary with a
//! `<file>.toml` description beside it. Every size is checked before it is used.

use super::{Dtype, StreamError, StreamLayout};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

fn le_u16(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}
fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}
fn le_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

/// A WAV or RF64 file's layout: integers are ±1 V full scale, floats volts (as
/// [`crate::ingest::wavfmt`] reads a one-hit WAV).
pub(crate) fn wav_layout(path: &Path) -> Result<StreamLayout, StreamError> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let len = f.metadata().map_err(|e| e.to_string())?.len();
    let mut head = [0u8; 12];
    f.read_exact(&mut head)
        .map_err(|_| "shorter than a WAV header".to_string())?;
    let rf64 = match &head[0..4] {
        b"RIFF" => false,
        b"RF64" => true,
        _ => return Err("not a RIFF/RF64 file".into()),
    };
    if &head[8..12] != b"WAVE" {
        return Err("not a WAVE file".into());
    }
    let (mut fmt, mut ds64_data, mut at) = (None, None, 12u64);
    // Chunks until `data`; each size checked against the file.
    loop {
        let mut ch = [0u8; 8];
        f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
        f.read_exact(&mut ch)
            .map_err(|_| "no data chunk before the file ends".to_string())?;
        let size = le_u32(&ch[4..8]) as u64;
        let body = at + 8;
        match &ch[0..4] {
            b"ds64" if rf64 => {
                let mut b = [0u8; 16];
                f.read_exact(&mut b)
                    .map_err(|_| "a ds64 chunk cut short".to_string())?;
                ds64_data = Some(le_u64(&b[8..16]));
            }
            b"fmt " => {
                if size < 16 || body + size > len {
                    return Err(format!("a fmt chunk of {size} bytes").into());
                }
                let mut b = vec![0u8; size.min(40) as usize];
                f.read_exact(&mut b).map_err(|e| e.to_string())?;
                fmt = Some(b);
            }
            b"data" => {
                let fmt = fmt.ok_or("a data chunk before the fmt chunk")?;
                let declared = match (rf64, size) {
                    (true, 0xFFFF_FFFF) => ds64_data.ok_or("RF64 without a ds64 size")?,
                    _ => size,
                };
                return wav_fmt(path, &fmt, body, declared);
            }
            _ => {}
        }
        let next = body + size + (size & 1);
        if next <= at || next > len {
            return Err(format!("a chunk at byte {at} runs past the file's end").into());
        }
        at = next;
    }
}

fn wav_fmt(path: &Path, fmt: &[u8], data: u64, declared: u64) -> Result<StreamLayout, StreamError> {
    let mut tag = le_u16(&fmt[0..2]);
    let channels = le_u16(&fmt[2..4]) as usize;
    let rate = le_u32(&fmt[4..8]) as f64;
    let bits = le_u16(&fmt[14..16]);
    if tag == 0xFFFE && fmt.len() >= 26 {
        tag = le_u16(&fmt[24..26]); // WAVE_FORMAT_EXTENSIBLE: the sub-format's tag
    }
    let dtype = match (tag, bits) {
        (1, 16) => Dtype::I16,
        (1, 24) => Dtype::I24,
        (1, 32) => Dtype::I32,
        (3, 32) => Dtype::F32,
        (3, 64) => Dtype::F64,
        _ => return Err(format!("WAV format tag {tag} with {bits} bits is not read").into()),
    };
    if channels == 0 || rate <= 0.0 {
        return Err(format!("{channels} channels at {rate} Hz").into());
    }
    let frame = (channels * dtype.bytes()) as u64;
    let unit_v = match dtype {
        Dtype::F32 | Dtype::F64 => 1.0,
        d => 1.0 / 2f64.powi(d.bytes() as i32 * 8 - 1),
    };
    Ok(StreamLayout {
        path: path.to_path_buf(),
        data_offset: data,
        frames: declared / frame,
        channels,
        rate_hz: rate,
        dtype,
        interleaved: true,
        unit_v,
        counted: false,
    })
}

/// A NumPy `.npy` array's layout: `shape` (n,) or (channels, n), little-endian int16 or
/// float32, C order (a Fortran-order array is refused). Its rate and scale come from
/// `[ingest] sample_rate_hz` and, for int16, a `.toml` beside it (`volts_per_unit`; else
/// the ±1 V full scale of a WAV).
pub(crate) fn npy_layout(path: &Path, rate_hz: f64) -> Result<StreamLayout, StreamError> {
    let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut pre = [0u8; 10];
    f.read_exact(&mut pre)
        .map_err(|_| "shorter than a .npy header".to_string())?;
    if &pre[0..6] != b"\x93NUMPY" {
        return Err("not a .npy file".into());
    }
    let (hlen, at) = match pre[6] {
        1 => (le_u16(&pre[8..10]) as u64, 10u64),
        2 | 3 => {
            let mut b = [0u8; 2];
            f.read_exact(&mut b).map_err(|e| e.to_string())?;
            (le_u32(&[pre[8], pre[9], b[0], b[1]]) as u64, 12u64)
        }
        v => return Err(format!(".npy version {v}").into()),
    };
    if hlen > 1 << 20 {
        return Err(format!("a .npy header of {hlen} bytes").into());
    }
    let mut h = vec![0u8; hlen as usize];
    f.seek(SeekFrom::Start(at)).map_err(|e| e.to_string())?;
    f.read_exact(&mut h)
        .map_err(|_| "a .npy header cut short".to_string())?;
    let h = String::from_utf8_lossy(&h).replace(' ', "");
    let field = |k: &str| {
        h.split(&format!("'{k}':"))
            .nth(1)
            .map(|r| r.to_string())
            .ok_or(format!("no '{k}' in the .npy header"))
    };
    let descr = field("descr")?;
    let dtype = if descr.starts_with("'<i2'") {
        Dtype::I16
    } else if descr.starts_with("'<f4'") {
        Dtype::F32
    } else {
        return Err(format!(
            "dtype {} (int16 and float32 are read)",
            descr.split(',').next().unwrap_or("")
        )
        .into());
    };
    if field("fortran_order")?.starts_with("True") {
        return Err("a Fortran-order array".into());
    }
    let shape = field("shape")?;
    let inner = shape
        .trim_start_matches('(')
        .split(')')
        .next()
        .unwrap_or("");
    let dims: Vec<u64> = inner
        .split(',')
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<u64>().map_err(|_| format!("shape ({inner})")))
        .collect::<Result<_, _>>()?;
    let (channels, frames) = match dims[..] {
        [n] => (1usize, n),
        [c, n] if c > 0 && c <= 4096 => (c as usize, n),
        _ => return Err(format!("shape ({inner}): 1-D or channels × samples").into()),
    };
    let toml = sidecar(path)?;
    let unit_v = match dtype {
        Dtype::I16 => unit_of(toml.and_then(|t| t.volts_per_unit), dtype)?,
        _ => 1.0,
    };
    Ok(StreamLayout {
        path: path.to_path_buf(),
        data_offset: at + hlen,
        frames,
        channels,
        rate_hz,
        dtype,
        interleaved: false,
        unit_v,
        counted: true,
    })
}

/// `<file>.toml` beside a raw stream (or a `.npy`): what the bytes are.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDescription {
    /// `int16` or `float32` (raw only).
    #[serde(default)]
    pub dtype: Option<String>,
    #[serde(default)]
    pub channels: Option<usize>,
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// Volts per stored unit.
    #[serde(default)]
    pub volts_per_unit: Option<f64>,
    /// Bytes before the first sample.
    #[serde(default)]
    pub header_bytes: u64,
}

/// Where a stream file's description would be: `x.bin` → `x.bin.toml`.
pub fn sidecar_path(path: &Path) -> PathBuf {
    let mut p = path.as_os_str().to_owned();
    p.push(".toml");
    PathBuf::from(p)
}

/// The description beside a stream file, if there is one.
pub(crate) fn sidecar(path: &Path) -> Result<Option<RawDescription>, StreamError> {
    let p = sidecar_path(path);
    if !p.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    toml::from_str(&text)
        .map(Some)
        .map_err(|e| format!("{}: {}", p.display(), e.to_string().replace('\n', " ")).into())
}

/// Volts per stored unit: as described (finite, > 0), else int16 at ±1 V full scale (as a
/// WAV's integers) and floats as volts.
fn unit_of(described: Option<f64>, dtype: Dtype) -> Result<f64, StreamError> {
    match described {
        Some(v) if v.is_finite() && v > 0.0 => Ok(v),
        Some(v) => Err(format!("volts_per_unit must be a number > 0, got {v}").into()),
        None => Ok(match dtype {
            Dtype::I16 => 1.0 / 32768.0,
            _ => 1.0,
        }),
    }
}

/// A raw binary stream's layout from its `.toml` description (interleaved channels).
pub(crate) fn raw_layout(path: &Path) -> Result<StreamLayout, StreamError> {
    let d = sidecar(path)?.ok_or("no .toml description beside the raw stream")?;
    let dtype = match d.dtype.as_deref() {
        Some("int16") => Dtype::I16,
        Some("float32") => Dtype::F32,
        other => return Err(format!("dtype {other:?}: int16 or float32").into()),
    };
    let channels = d.channels.unwrap_or(1);
    let rate = d
        .sample_rate_hz
        .ok_or("no sample_rate_hz in the description")?;
    if channels == 0 || channels > 4096 || !(rate.is_finite() && rate > 0.0) {
        return Err(format!("{channels} channels at {rate} Hz").into());
    }
    let len = std::fs::metadata(path).map_err(|e| e.to_string())?.len();
    let frame = (channels * dtype.bytes()) as u64;
    Ok(StreamLayout {
        path: path.to_path_buf(),
        data_offset: d.header_bytes,
        frames: len.saturating_sub(d.header_bytes) / frame,
        channels,
        rate_hz: rate,
        dtype,
        interleaved: true,
        unit_v: unit_of(d.volts_per_unit, dtype)?,
        counted: true,
    })
}
