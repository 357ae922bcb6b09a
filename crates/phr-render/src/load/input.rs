//! Reading the files a scene names, with bounds: every mesh, material library, glTF buffer and
//! scene file goes through [`read_file`], so none of them can be a device (`/dev/zero` is read
//! for ever), a folder or a file too large to be a mesh, and a gzipped file cannot inflate
//! past [`MAX_FILE_BYTES`] (a 21 MB "zip bomb" inflating to 20 GiB exhausted memory before).

use crate::error::LoadError;
use std::io::Read;
use std::path::Path;

/// The most bytes one input file may hold, compressed or inflated: 2 GiB, about 80 million
/// triangles of binary PLY, ten times the largest scene we render (eight dragons).
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// A UTF-8 byte-order mark, which some editors put before text (it made the first OBJ vertex
/// vanish and every index shift).
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Reads a whole regular file of at most [`MAX_FILE_BYTES`]; `what` names it in errors
/// ("material library", "buffer 0", ...), `path` is the file the error is about.
pub fn read_file(path: &Path, what: &str) -> Result<Vec<u8>, LoadError> {
    let fail = |message: String| LoadError::new(path, message);
    let meta = std::fs::metadata(path).map_err(|e| fail(format!("cannot open {what}: {e}")))?;
    if !meta.is_file() {
        return Err(fail(format!("{what} is not a regular file")));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(fail(format!("{what} is larger than {}", human_bytes(MAX_FILE_BYTES))));
    }
    let file = std::fs::File::open(path).map_err(|e| fail(format!("cannot open {what}: {e}")))?;
    read_bounded(file, MAX_FILE_BYTES, path, what)
}

/// Decodes an image held in memory (its format recognised by content, within the `image`
/// crate's default allocation limits), refusing formats other than `allowed`; `name` (a file,
/// or an image inside an asset) and `what` ("texture", "environment map") name it in errors.
pub fn decode_image(
    bytes: &[u8],
    name: &str,
    what: &str,
    allowed: &[image::ImageFormat],
) -> Result<image::DynamicImage, LoadError> {
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| LoadError::new(name, format!("cannot read the {what}: {e}")))?;
    match reader.format() {
        Some(format) if allowed.contains(&format) => {}
        found => {
            let names: Vec<&str> = allowed.iter().map(|f| f.extensions_str()[0]).collect();
            let found = found.map_or("an unknown format".to_string(), |f| format!("{f:?}"));
            return Err(LoadError::new(name, format!("the {what} is {found}, not one of {}", names.join(", "))));
        }
    }
    let image = reader.decode().map_err(|e| LoadError::new(name, format!("cannot decode the {what}: {e}")))?;
    if image.width() == 0 || image.height() == 0 {
        return Err(LoadError::new(name, format!("the {what} has no pixels")));
    }
    Ok(image)
}

/// Inflates gzip data (all members) to at most [`MAX_FILE_BYTES`].
pub fn gunzip(path: &Path, compressed: &[u8]) -> Result<Vec<u8>, LoadError> {
    gunzip_at_most(path, compressed, MAX_FILE_BYTES)
}

fn gunzip_at_most(path: &Path, compressed: &[u8], limit: u64) -> Result<Vec<u8>, LoadError> {
    read_bounded(flate2::read::MultiGzDecoder::new(compressed), limit, path, "the decompressed data")
        .map_err(|e| LoadError::new(path, format!("cannot decompress: {}", e.message)))
}

/// Reads `source` to its end, failing as soon as it yields more than `limit` bytes.
fn read_bounded(source: impl Read, limit: u64, path: &Path, what: &str) -> Result<Vec<u8>, LoadError> {
    let mut out = Vec::new();
    source
        .take(limit + 1)
        .read_to_end(&mut out)
        .map_err(|e| LoadError::new(path, format!("cannot read {what}: {e}")))?;
    if out.len() as u64 > limit {
        return Err(LoadError::new(path, format!("{what} is larger than {}", human_bytes(limit))));
    }
    Ok(out)
}

fn human_bytes(n: u64) -> String {
    match n {
        n if n >= 1 << 30 => format!("{} GiB", n >> 30),
        n if n >= 1 << 20 => format!("{} MiB", n >> 20),
        n => format!("{n} bytes"),
    }
}

/// `bytes` without a leading UTF-8 byte-order mark.
pub fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(BOM).unwrap_or(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_folders_are_refused() {
        let dir = std::env::temp_dir();
        assert!(read_file(&dir, "mesh").unwrap_err().message.contains("not a regular file"));
        #[cfg(unix)]
        assert!(read_file(Path::new("/dev/zero"), "buffer 0").unwrap_err().message.contains("not a regular file"));
    }

    /// A gzip member of 4 MiB of zeros (4 KiB compressed) stops at a 1 MiB limit with an
    /// error, having inflated no more than the limit; within the limit it inflates whole.
    #[test]
    fn inflation_stops_at_the_limit() {
        use std::io::Write;
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        encoder.write_all(&vec![0u8; 4 << 20]).unwrap();
        let bomb = encoder.finish().unwrap();
        assert!(bomb.len() < 64 << 10, "{} bytes", bomb.len());
        let e = gunzip_at_most(Path::new("bomb.obj.gz"), &bomb, 1 << 20).unwrap_err();
        assert!(
            e.to_string().contains("bomb.obj.gz: cannot decompress: the decompressed data is larger than 1 MiB"),
            "{e}"
        );
        assert_eq!(gunzip_at_most(Path::new("ok.obj.gz"), &bomb, 4 << 20).unwrap().len(), 4 << 20);
    }

    #[test]
    fn the_byte_order_mark_goes() {
        assert_eq!(strip_bom(b"\xEF\xBB\xBFv 1 2 3"), b"v 1 2 3");
        assert_eq!(strip_bom(b"v 1 2 3"), b"v 1 2 3");
    }
}
