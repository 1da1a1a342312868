//! The bytes of a glTF file's buffers: the GLB binary chunk, `data:` URIs (base64) and files
//! named by relative URIs (percent-encoded, resolved by the caller).

use std::path::Path;

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine;

use super::parse_error;
use crate::model::scene::mtl::preview;
use crate::model::scene::SceneError;

/// Base64 as `data:` URIs carry it, padded or not.
const BASE64: GeneralPurpose = GeneralPurpose::new(
    &base64::alphabet::STANDARD,
    GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
);

/// Finds the file a relative buffer URI names (already percent-decoded) and returns its bytes,
/// or `Ok(None)` when no such file exists.
pub type BufferResolver<'a> = dyn FnMut(&str) -> Result<Option<Vec<u8>>, SceneError> + 'a;

/// The bytes of every buffer of `document`, in buffer order; `blob` is the GLB binary chunk and
/// `path` names the glTF file in errors. Each buffer must hold at least its `byteLength` bytes.
///
/// Errors: [`SceneError::Parse`] naming the file and buffer for a missing binary chunk or file,
/// a URI with a scheme other than `data:`, a `data:` URI that is not base64, malformed base64
/// or percent-encoding, or a buffer shorter than its `byteLength`; whatever `resolve` returns.
pub fn load_buffers(
    document: &::gltf::Document,
    blob: Option<&[u8]>,
    path: &Path,
    resolve: &mut BufferResolver<'_>,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let i = buffer.index();
        let fail = |reason: String| parse_error(path, format!("buffer {i}: {reason}"));
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => blob
                .ok_or_else(|| fail("it is the GLB binary chunk, but the file has none".into()))?
                .to_vec(),
            ::gltf::buffer::Source::Uri(uri) => match uri.strip_prefix("data:") {
                Some(data) => decode_data_uri(data).map_err(fail)?,
                None => {
                    let name = relative_path(uri).map_err(fail)?;
                    resolve(&name)?
                        .ok_or_else(|| fail(format!("the file '{name}' does not exist")))?
                }
            },
        };
        if data.len() < buffer.length() {
            return Err(fail(format!(
                "holds {} bytes but its byteLength is {}",
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The bytes of a `data:` URI's text after `data:` (`<media type>;base64,<data>`).
fn decode_data_uri(data: &str) -> Result<Vec<u8>, String> {
    let (header, payload) = data
        .split_once(',')
        .ok_or("a data: URI without ',' before its data")?;
    if !header.ends_with(";base64") {
        return Err(format!(
            "data:{} URI is not base64 (vtq reads base64 data: URIs)",
            preview(header)
        ));
    }
    BASE64
        .decode(payload.trim_end())
        .map_err(|e| format!("malformed base64 in a data: URI: {e}"))
}

/// The relative path a buffer URI names: percent-decoded, without a scheme.
fn relative_path(uri: &str) -> Result<String, String> {
    let scheme = uri
        .split_once(':')
        .map(|(s, _)| s)
        .filter(|s| s.len() > 1 && s.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'+'));
    if let Some(scheme) = scheme {
        return Err(format!(
            "URI scheme '{}:' is not supported (vtq reads data: URIs and relative paths)",
            preview(scheme)
        ));
    }
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("malformed percent-encoding in '{}'", preview(uri)))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("'{}' decodes to invalid UTF-8", preview(uri)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_uris_and_relative_paths() {
        assert_eq!(
            decode_data_uri("application/octet-stream;base64,AAEC").unwrap(),
            [0, 1, 2]
        );
        assert_eq!(
            decode_data_uri("application/gltf-buffer;base64,AAE").unwrap(),
            [0, 1]
        );
        assert!(decode_data_uri("text/plain,abc")
            .unwrap_err()
            .contains("not base64"));
        assert!(decode_data_uri(";base64,***")
            .unwrap_err()
            .contains("base64"));
        assert_eq!(relative_path("my%20mesh.bin").unwrap(), "my mesh.bin");
        assert_eq!(relative_path("dir/a.bin").unwrap(), "dir/a.bin");
        assert!(relative_path("http://x/a.bin")
            .unwrap_err()
            .contains("http:"));
        assert!(relative_path("a%2").unwrap_err().contains("percent"));
        assert!(relative_path("a%ff.bin").unwrap_err().contains("UTF-8"));
    }
}
