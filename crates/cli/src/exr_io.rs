//! Reading and writing visibility images (OpenEXR) and PNG previews.
//!
//! The EXR layout follows the contract exactly (docs/methods.md §11, "Visibility
//! image"): one float32 channel per quantity, one pixel per camera pixel, row 0
//! at the top. The channels that every visibility image carries are
//! [`CHANNEL_V`] (fraction of the light's area visible, NaN on background
//! pixels) and [`CHANNEL_Z`] (view-space depth, +inf on background pixels);
//! more channels may be added under their own names.
//!
//! Every writer in this module is atomic: the data goes to a temporary file in
//! the target's directory (`.{name}.tmp-{pid}-{n}`), which is flushed, synced
//! and then renamed onto the target. On any error the temporary file is removed
//! and the target is left untouched, so a failed run never leaves a partial or
//! truncated output behind.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    SmallVec, Text, WritableImage,
};

mod first_layer;

/// Name of the visibility channel: the fraction of the light's area visible
/// from the surface point seen through the pixel (NaN on background pixels).
pub const CHANNEL_V: &str = "V";

/// Name of the depth channel: view-space depth of the surface point seen
/// through the pixel (+inf on background pixels).
pub const CHANNEL_Z: &str = "Z";

/// An error while building, reading or writing an image.
///
/// Every variant that concerns a file names it, and every message is a single
/// line, suitable for the command line's one-line error on standard error.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// A file could not be opened, decoded or is not a valid visibility image.
    #[error("cannot read {}: {reason}", path.display())]
    Read {
        /// The file that was being read.
        path: PathBuf,
        /// What went wrong, in one line.
        reason: String,
    },

    /// A file could not be written; nothing was left at `path`.
    #[error("cannot write {}: {reason}", path.display())]
    Write {
        /// The file that was being written.
        path: PathBuf,
        /// What went wrong, in one line.
        reason: String,
    },

    /// A file read as a visibility image lacks a required channel.
    #[error("{}: no channel `{channel}` (a visibility image needs `V` and `Z`)", path.display())]
    MissingChannel {
        /// The file that was read.
        path: PathBuf,
        /// The channel that is missing.
        channel: String,
    },

    /// An in-memory image lacks a channel that an operation needs (e.g. scoring).
    #[error("the {role} image has no channel `{channel}`")]
    NoChannel {
        /// Which image: `"candidate"` or `"reference"`.
        role: &'static str,
        /// The channel that is missing.
        channel: String,
    },

    /// A channel does not hold exactly one sample per pixel.
    #[error("channel `{channel}` has {found} samples, expected {expected} (width x height)")]
    ChannelLength {
        /// The channel's name.
        channel: String,
        /// `width * height` of the image.
        expected: usize,
        /// The number of samples given.
        found: usize,
    },

    /// A channel with this name is already present in the image.
    #[error("channel `{channel}` is already present in the image")]
    DuplicateChannel {
        /// The channel's name.
        channel: String,
    },

    /// Two images that must have the same size do not.
    #[error(
        "image sizes differ: candidate is {}x{}, reference is {}x{}",
        candidate.0, candidate.1, reference.0, reference.1
    )]
    SizeMismatch {
        /// `(width, height)` of the candidate image.
        candidate: (usize, usize),
        /// `(width, height)` of the reference image.
        reference: (usize, usize),
    },
}

/// A visibility image: a list of named float channels over `width x height`
/// pixels, each stored row-major with row 0 at the top
/// (sample index = `row * width + column`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VisibilityImage {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// The channels, each `(name, samples)` with `width * height` samples.
    /// Names are unique. After [`read_exr`] the order is the file's, which is
    /// alphabetical (EXR sorts channels by name).
    pub channels: Vec<(String, Vec<f32>)>,
    /// String header attributes `(name, value)`: the contract's provenance
    /// (`softshadow.algo`, `.backend`, `.params`, `.version`, `.scene`; [`PROVENANCE`]).
    /// [`read_exr`] returns every string attribute of the file's header.
    pub attributes: Vec<(String, String)>,
}

/// The contract's provenance attributes, in the order `score` prints them.
pub const PROVENANCE: [&str; 5] = [
    "softshadow.algo",
    "softshadow.backend",
    "softshadow.params",
    "softshadow.version",
    "softshadow.scene",
];

impl VisibilityImage {
    /// An image of `width x height` pixels with no channels yet.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            channels: Vec::new(),
            attributes: Vec::new(),
        }
    }

    /// `width * height` (saturating, so that absurd sizes cannot overflow).
    pub fn pixel_count(&self) -> usize {
        self.width.saturating_mul(self.height)
    }

    /// Adds a channel. Fails with [`ImageError::ChannelLength`] unless `data`
    /// holds exactly `width * height` samples, and with
    /// [`ImageError::DuplicateChannel`] if a channel of that name exists.
    pub fn push_channel(
        &mut self,
        name: impl Into<String>,
        data: Vec<f32>,
    ) -> Result<(), ImageError> {
        let name = name.into();
        if data.len() != self.pixel_count() {
            return Err(ImageError::ChannelLength {
                channel: name,
                expected: self.pixel_count(),
                found: data.len(),
            });
        }
        if self.channel(&name).is_some() {
            return Err(ImageError::DuplicateChannel { channel: name });
        }
        self.channels.push((name, data));
        Ok(())
    }

    /// The samples of the channel called `name`, if present.
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, data)| data.as_slice())
    }
}

/// Writes `img` as a single-part, scanline OpenEXR file with every channel
/// stored as float32, ZIP-compressed (lossless: every bit, NaN payloads and
/// infinities included, reads back unchanged).
///
/// The write is atomic (see the module documentation): on error nothing is
/// left at `path` and no temporary file remains. The image must have a
/// non-zero size, at least one channel, unique non-empty channel names made
/// of Latin-1 characters, and `width * height` samples in every channel.
pub fn write_exr(path: &Path, img: &VisibilityImage) -> Result<(), ImageError> {
    let fail = |reason: String| ImageError::Write {
        path: path.to_path_buf(),
        reason,
    };
    if img.width == 0 || img.height == 0 {
        return Err(fail(format!(
            "the image is {}x{}; an EXR needs at least one pixel",
            img.width, img.height
        )));
    }
    if img.channels.is_empty() {
        return Err(fail("the image has no channels".to_string()));
    }
    let expected = img.pixel_count();
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (i, (name, data)) in img.channels.iter().enumerate() {
        if data.len() != expected {
            return Err(fail(format!(
                "channel `{name}` has {} samples, expected {expected}",
                data.len()
            )));
        }
        if img.channels[..i].iter().any(|(other, _)| other == name) {
            return Err(fail(format!("channel `{name}` appears twice")));
        }
        let text = match Text::new_or_none(name) {
            Some(text) if !name.is_empty() => text,
            _ => {
                return Err(fail(format!(
                    "channel name `{name}` is empty or not representable in EXR"
                )))
            }
        };
        list.push(AnyChannel::new(text, FlatSamples::F32(data.clone())));
    }

    let mut attributes = LayerAttributes::default();
    for (name, value) in &img.attributes {
        let (Some(key), Some(text)) = (Text::new_or_none(name), Text::new_or_none(latin1(value)))
        else {
            return Err(fail(format!(
                "attribute `{name}` is not representable in EXR"
            )));
        };
        attributes.other.insert(key, AttributeValue::Text(text));
    }
    let layer = Layer::new(
        (img.width, img.height),
        attributes,
        Encoding::SMALL_LOSSLESS, // ZIP16, scan lines, increasing line order
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);

    write_atomic(path, |writer| {
        image.write().to_buffered(writer).map_err(|e| e.to_string())
    })
}

/// `value` with every character outside Latin-1 (EXR text) replaced by `?`: a scene path in
/// another script keeps its shape.
fn latin1(value: &str) -> String {
    value
        .chars()
        .map(|c| if (c as u32) < 256 { c } else { '?' })
        .collect()
}

/// Reads every channel of the first layer of an OpenEXR file, converting
/// f16 and u32 samples to f32 (u32 values above 2^24 lose precision).
/// Row 0 of the result is the top row of the image.
///
/// Deep data, subsampled channels and unreadable or malformed files give
/// [`ImageError::Read`] naming the file; this function does not panic on bad
/// input. It does not require any particular channel: see
/// [`read_visibility_exr`] for that.
pub fn read_exr(path: &Path) -> Result<VisibilityImage, ImageError> {
    let fail = |reason: String| ImageError::Read {
        path: path.to_path_buf(),
        reason,
    };
    let read = catch_unwind(AssertUnwindSafe(|| first_layer::read_first_layer(path)));
    let image = match read {
        Ok(Ok(image)) => image,
        Ok(Err(e)) => return Err(fail(one_line(&e.to_string()))),
        Err(_) => return Err(fail("the EXR decoder failed on this file".to_string())),
    };

    let layer = image.layer_data;
    let width = layer.size.width();
    let height = layer.size.height();
    let mut out = VisibilityImage::new(width, height);
    let mut text_attributes: Vec<(String, String)> = image
        .attributes
        .other
        .iter()
        .chain(layer.attributes.other.iter())
        .filter_map(|(k, v)| match v {
            AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
            _ => None,
        })
        .collect();
    text_attributes.sort();
    text_attributes.dedup();
    out.attributes = text_attributes;
    for channel in layer.channel_data.list.iter() {
        let name = channel.name.to_string();
        let data: Vec<f32> = match &channel.sample_data {
            FlatSamples::F32(samples) => samples.clone(),
            other => other.values_as_f32().collect(),
        };
        if data.len() != out.pixel_count() {
            return Err(fail(format!(
                "channel `{name}` has {} samples for {width}x{height} pixels (subsampled channels are not supported)",
                data.len()
            )));
        }
        out.push_channel(name, data)
            .map_err(|e| fail(e.to_string()))?;
    }
    Ok(out)
}

/// Reads a visibility image with [`read_exr`] and checks that it has the
/// contract's `V` and `Z` channels ([`ImageError::MissingChannel`] naming the
/// file otherwise).
pub fn read_visibility_exr(path: &Path) -> Result<VisibilityImage, ImageError> {
    let img = read_exr(path)?;
    for channel in [CHANNEL_V, CHANNEL_Z] {
        if img.channel(channel).is_none() {
            return Err(ImageError::MissingChannel {
                path: path.to_path_buf(),
                channel: channel.to_string(),
            });
        }
    }
    Ok(img)
}

/// Colour of background pixels (V = NaN) in [`write_png_preview`]: dark blue.
pub const PREVIEW_BACKGROUND: [u8; 3] = [16, 24, 72];

/// Writes an 8-bit RGB PNG preview of a visibility channel `v` of
/// `width x height` samples (row 0 at the top).
///
/// V is clamped to [0, 1] (+inf counts as 1, -inf as 0) and encoded with the
/// sRGB transfer function, since V is a linear fraction of light: V = 0.5
/// shows as the grey that looks half as bright as white (8-bit value 188).
/// NaN (background) is drawn as [`PREVIEW_BACKGROUND`], a dark blue.
/// The write is atomic; a wrong sample count gives [`ImageError::Write`].
pub fn write_png_preview(
    path: &Path,
    width: usize,
    height: usize,
    v: &[f32],
) -> Result<(), ImageError> {
    let mut rgb = Vec::with_capacity(v.len().saturating_mul(3));
    for &x in v {
        if x.is_nan() {
            rgb.extend_from_slice(&PREVIEW_BACKGROUND);
        } else {
            let g = srgb_encode(x);
            rgb.extend_from_slice(&[g, g, g]);
        }
    }
    write_rgb_png(path, width, height, &rgb)
}

/// Writes 8-bit RGB pixels (`3 * width * height` bytes, row 0 at the top) as a
/// PNG file, atomically. Shared by the preview and the error image writers.
pub(crate) fn write_rgb_png(
    path: &Path,
    width: usize,
    height: usize,
    rgb: &[u8],
) -> Result<(), ImageError> {
    use image::ImageEncoder;

    let fail = |reason: String| ImageError::Write {
        path: path.to_path_buf(),
        reason,
    };
    let expected = width.saturating_mul(height);
    if rgb.len() != expected.saturating_mul(3) {
        return Err(fail(format!(
            "got {} pixels for a {width}x{height} image",
            rgb.len() / 3
        )));
    }
    if width == 0 || height == 0 {
        return Err(fail(format!(
            "the image is {width}x{height}; a PNG needs at least one pixel"
        )));
    }
    let (w, h) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => (w, h),
        _ => return Err(fail(format!("{width}x{height} is too large for PNG"))),
    };
    write_atomic(path, |writer| {
        image::codecs::png::PngEncoder::new(writer)
            .write_image(rgb, w, h, image::ExtendedColorType::Rgb8)
            .map_err(|e| e.to_string())
    })
}

/// The sRGB transfer function applied to a linear value, clamped to [0, 1]
/// and rounded to 8 bits. NaN must be handled by the caller (it gives 0).
fn srgb_encode(x: f32) -> u8 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    let y = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    // y is in [0, 1]; the cast saturates anyway.
    (y * 255.0 + 0.5) as u8
}

/// Distinguishes temporary files of concurrent writes within one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary file used while writing `path`: `.{name}.tmp-{pid}-{n}` in
/// the same directory, so that the final rename stays on one file system.
fn temp_path_for(path: &Path) -> Result<PathBuf, ImageError> {
    let name = path.file_name().ok_or_else(|| ImageError::Write {
        path: path.to_path_buf(),
        reason: "the path does not name a file".to_string(),
    })?;
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let tmp_name = format!(
        ".{}.tmp-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        n
    );
    Ok(match path.parent() {
        Some(dir) => dir.join(tmp_name),
        None => PathBuf::from(tmp_name),
    })
}

/// Runs `write` on a buffered temporary file next to `path`, then flushes,
/// syncs and renames it onto `path`. On any error (or a panic inside `write`)
/// the temporary file is removed and `path` is left as it was.
fn write_atomic<F>(path: &Path, write: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<(), String>,
{
    let tmp = temp_path_for(path)?;
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| ImageError::Write {
            path: path.to_path_buf(),
            reason: format!("cannot create a temporary file {}: {e}", tmp.display()),
        })?;

    let result = (|| -> Result<(), String> {
        let mut writer = BufWriter::new(file);
        match catch_unwind(AssertUnwindSafe(|| write(&mut writer))) {
            Ok(result) => result?,
            Err(_) => return Err("the encoder failed".to_string()),
        }
        writer.flush().map_err(|e| e.to_string())?;
        let file = writer.into_inner().map_err(|e| e.error().to_string())?;
        file.sync_all().map_err(|e| e.to_string())?;
        drop(file);
        std::fs::rename(&tmp, path).map_err(|e| e.to_string())
    })();

    result.map_err(|reason| {
        let _ = std::fs::remove_file(&tmp);
        ImageError::Write {
            path: path.to_path_buf(),
            reason: one_line(&reason),
        }
    })
}

/// Collapses a possibly multi-line message into one line.
fn one_line(message: &str) -> String {
    message.split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir_entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    fn sample_image() -> VisibilityImage {
        let (w, h) = (5, 3);
        let n = w * h;
        let mut v: Vec<f32> = (0..n).map(|i| i as f32 / n as f32).collect();
        let mut z: Vec<f32> = (0..n).map(|i| 1.0 + i as f32 * 0.37).collect();
        // Background pixels, a NaN with a payload, special values.
        v[0] = f32::NAN;
        z[0] = f32::INFINITY;
        v[7] = f32::from_bits(0x7fc0_1234);
        z[7] = f32::INFINITY;
        v[3] = -0.0;
        v[4] = f32::from_bits(1); // smallest subnormal
        z[14] = f32::MAX;
        let extra: Vec<f32> = (0..n).map(|i| (i as f32).sin() * 1e-3).collect();
        let mut img = VisibilityImage::new(w, h);
        img.push_channel("V", v).unwrap();
        img.push_channel("Z", z).unwrap();
        img.push_channel("kernel_size", extra).unwrap();
        img
    }

    fn bits(data: &[f32]) -> Vec<u32> {
        data.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn exr_round_trip_is_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.exr");
        let img = sample_image();
        write_exr(&path, &img).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!((back.width, back.height), (img.width, img.height));
        assert_eq!(back.channels.len(), 3);
        for (name, data) in &img.channels {
            let read = back.channel(name).unwrap();
            assert_eq!(bits(read), bits(data), "channel {name}");
        }
        assert!(back.channel("V").unwrap()[0].is_nan());
        assert_eq!(back.channel("Z").unwrap()[0], f32::INFINITY);
        // Only the target is left in the directory.
        assert_eq!(dir_entries(dir.path()), vec!["out.exr".to_string()]);
        // The strict reader accepts it too.
        read_visibility_exr(&path).unwrap();
    }

    /// String attributes (the contract's provenance) survive a write and a read, and a value
    /// outside Latin-1 keeps its shape.
    #[test]
    fn attributes_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.exr");
        let mut img = sample_image();
        img.attributes = vec![
            ("softshadow.algo".into(), "pcss".into()),
            ("softshadow.params".into(), r#"{"resolution":"256"}"#.into()),
            ("softshadow.scene".into(), "scènes/兔.toml".into()),
        ];
        write_exr(&path, &img).unwrap();
        let back = read_exr(&path).unwrap();
        let get = |k: &str| {
            back.attributes
                .iter()
                .find(|(n, _)| n == k)
                .map(|(_, v)| v.clone())
        };
        assert_eq!(get("softshadow.algo").as_deref(), Some("pcss"));
        assert_eq!(
            get("softshadow.params").as_deref(),
            Some(r#"{"resolution":"256"}"#)
        );
        assert_eq!(get("softshadow.scene").as_deref(), Some("scènes/?.toml"));
    }

    #[test]
    fn rows_are_stored_top_down() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rows.exr");
        let (w, h) = (3, 4);
        let v: Vec<f32> = (0..w * h).map(|i| (i / w) as f32).collect(); // value = row
        let mut img = VisibilityImage::new(w, h);
        img.push_channel("V", v.clone()).unwrap();
        write_exr(&path, &img).unwrap();
        let back = read_exr(&path).unwrap();
        assert_eq!(back.channel("V").unwrap(), v.as_slice());
        // Cross-check the stored order with exr's own pixel accessor.
        let raw = first_layer::read_first_layer(&path).unwrap();
        let layer = raw.layer_data;
        let top_left = layer.channel_data.list[0]
            .sample_data
            .value_by_flat_index(0)
            .to_f32();
        assert_eq!(top_left, 0.0);
        assert_eq!(layer.encoding.blocks, exr::prelude::Blocks::ScanLines);
        assert_eq!(layer.encoding.compression, exr::prelude::Compression::ZIP16);
        assert!(matches!(
            layer.channel_data.list[0].sample_data,
            FlatSamples::F32(_)
        ));
    }

    #[test]
    fn channel_length_mismatch_is_an_error() {
        let mut img = VisibilityImage::new(4, 2);
        let err = img.push_channel("V", vec![0.0; 7]).unwrap_err();
        assert!(matches!(
            err,
            ImageError::ChannelLength {
                expected: 8,
                found: 7,
                ..
            }
        ));
        assert!(err.to_string().contains("`V`"));
        img.push_channel("V", vec![0.0; 8]).unwrap();
        let err = img.push_channel("V", vec![0.0; 8]).unwrap_err();
        assert!(matches!(err, ImageError::DuplicateChannel { .. }));

        // A hand-built image with a wrong length is refused by the writer.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.exr");
        let bad = VisibilityImage {
            width: 4,
            height: 2,
            channels: vec![("V".into(), vec![0.0; 3])],
            attributes: Vec::new(),
        };
        let err = write_exr(&path, &bad).unwrap_err();
        assert!(matches!(err, ImageError::Write { .. }));
        assert!(!path.exists());
        assert!(dir_entries(dir.path()).is_empty());
    }

    #[test]
    fn reading_missing_or_garbage_files_names_the_path() {
        let dir = tempfile::tempdir().unwrap();

        let missing = dir.path().join("nope.exr");
        let err = read_exr(&missing).unwrap_err();
        assert!(matches!(err, ImageError::Read { .. }));
        assert!(err.to_string().contains("nope.exr"), "{err}");

        let garbage = dir.path().join("garbage.exr");
        std::fs::write(&garbage, b"this is not an OpenEXR file at all").unwrap();
        let err = read_exr(&garbage).unwrap_err();
        assert!(err.to_string().contains("garbage.exr"), "{err}");
        assert!(!err.to_string().contains('\n'));

        // A truncated real EXR.
        let good = dir.path().join("good.exr");
        write_exr(&good, &sample_image()).unwrap();
        let bytes = std::fs::read(&good).unwrap();
        let truncated = dir.path().join("truncated.exr");
        std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
        let err = read_exr(&truncated).unwrap_err();
        assert!(err.to_string().contains("truncated.exr"), "{err}");

        // An empty file.
        let empty = dir.path().join("empty.exr");
        std::fs::write(&empty, b"").unwrap();
        assert!(read_exr(&empty).is_err());

        // A valid EXR without Z is refused by the strict reader.
        let only_v = dir.path().join("only_v.exr");
        let mut img = VisibilityImage::new(2, 2);
        img.push_channel("V", vec![0.5; 4]).unwrap();
        write_exr(&only_v, &img).unwrap();
        let err = read_visibility_exr(&only_v).unwrap_err();
        assert!(
            matches!(&err, ImageError::MissingChannel { channel, .. } if channel == "Z"),
            "{err}"
        );
        assert!(err.to_string().contains("only_v.exr"));
    }

    #[test]
    fn atomic_write_into_missing_directory_creates_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("no_such_dir").join("out.exr");
        let err = write_exr(&target, &sample_image()).unwrap_err();
        assert!(matches!(err, ImageError::Write { .. }));
        assert!(err.to_string().contains("out.exr"), "{err}");
        assert!(!target.exists());
        assert!(dir_entries(dir.path()).is_empty());

        let png = dir.path().join("no_such_dir").join("out.png");
        let err = write_png_preview(&png, 1, 1, &[0.5]).unwrap_err();
        assert!(matches!(err, ImageError::Write { .. }));
        assert!(dir_entries(dir.path()).is_empty());
    }

    #[test]
    fn failed_write_leaves_existing_target_and_no_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.exr");
        std::fs::write(&target, b"previous").unwrap();
        let empty = VisibilityImage::new(3, 3); // no channels: refused
        assert!(write_exr(&target, &empty).is_err());
        assert_eq!(std::fs::read(&target).unwrap(), b"previous");

        // The rename fails when the target is a directory: temp file removed.
        let target_dir = dir.path().join("is_a_dir.exr");
        std::fs::create_dir(&target_dir).unwrap();
        std::fs::write(target_dir.join("keep"), b"x").unwrap();
        assert!(write_exr(&target_dir, &sample_image()).is_err());
        assert_eq!(
            dir_entries(dir.path()),
            vec!["is_a_dir.exr".to_string(), "out.exr".to_string()]
        );

        // A successful overwrite replaces the target and leaves no temp file.
        write_exr(&target, &sample_image()).unwrap();
        assert_eq!(read_exr(&target).unwrap().channels.len(), 3);
        assert_eq!(
            dir_entries(dir.path()),
            vec!["is_a_dir.exr".to_string(), "out.exr".to_string()]
        );
    }

    #[test]
    fn png_preview_colours() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("preview.png");
        let v = [0.0, 1.0, f32::NAN, 0.5, 2.0, f32::INFINITY];
        write_png_preview(&path, 3, 2, &v).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (3, 2));
        assert_eq!(img.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(img.get_pixel(1, 0).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(2, 0).0, PREVIEW_BACKGROUND);
        assert_eq!(img.get_pixel(0, 1).0, [188, 188, 188]);
        assert_eq!(img.get_pixel(1, 1).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(2, 1).0, [255, 255, 255]);
        assert_eq!(dir_entries(dir.path()), vec!["preview.png".to_string()]);

        let err = write_png_preview(&path, 2, 2, &v).unwrap_err();
        assert!(matches!(err, ImageError::Write { .. }));
    }
}
