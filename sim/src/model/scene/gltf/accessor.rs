//! Reading glTF accessors with every bound checked: positions (`VEC3` of `FLOAT`) and vertex
//! indices (`SCALAR` of `UNSIGNED_BYTE`, `UNSIGNED_SHORT` or `UNSIGNED_INT`), from buffer views
//! with or without a byte stride, and sparse accessors (with or without a base view).
//!
//! vtq reads accessors itself rather than through the `gltf` crate's reader, which trusts the
//! file: it slices and subtracts without checks, so a malformed file could panic. Here a range
//! beyond its buffer view or buffer, a stride shorter than an element, a sparse index beyond
//! the accessor or an unexpected type is an error naming the accessor.

use ::gltf::accessor::{sparse::IndexType, Accessor, DataType, Dimensions};
use glam::Vec3;

/// The most elements an accessor without a buffer view (zeros, plus its sparse values) may
/// have: its count is not backed by bytes of the file, so it is bounded here.
pub const MAX_UNBACKED_ELEMENTS: usize = 1 << 20;

/// The positions of a `POSITION` accessor (`VEC3` of `FLOAT`, not normalized).
pub fn read_positions(accessor: &Accessor<'_>, buffers: &[Vec<u8>]) -> Result<Vec<Vec3>, String> {
    let i = accessor.index();
    if accessor.dimensions() != Dimensions::Vec3
        || accessor.data_type() != DataType::F32
        || accessor.normalized()
    {
        return Err(format!(
            "accessor {i} (POSITION) is {} of {}{}; vtq reads VEC3 of FLOAT positions",
            dimensions_name(accessor.dimensions()),
            type_name(accessor.data_type()),
            if accessor.normalized() {
                ", normalized"
            } else {
                ""
            }
        ));
    }
    read(accessor, buffers, 12, |b| {
        Vec3::new(f32_at(b, 0), f32_at(b, 4), f32_at(b, 8))
    })
}

/// The vertex indices of an index accessor (`SCALAR` of an unsigned integer type).
pub fn read_indices(accessor: &Accessor<'_>, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    let i = accessor.index();
    if accessor.dimensions() != Dimensions::Scalar {
        return Err(format!(
            "accessor {i} (indices) is {}; indices are SCALAR",
            dimensions_name(accessor.dimensions())
        ));
    }
    match accessor.data_type() {
        DataType::U8 => read(accessor, buffers, 1, |b| u32::from(b[0])),
        DataType::U16 => read(accessor, buffers, 2, |b| u32::from(u16_at(b, 0))),
        DataType::U32 => read(accessor, buffers, 4, |b| u32_at(b, 0)),
        other => Err(format!(
            "accessor {i} (indices) is of {}; indices are UNSIGNED_BYTE, UNSIGNED_SHORT or \
             UNSIGNED_INT",
            type_name(other)
        )),
    }
}

/// The elements of `accessor`, each `size` bytes decoded by `decode` (given exactly `size`
/// bytes): from its buffer view (zeros without one), then its sparse values substituted.
fn read<T: Copy + Default>(
    accessor: &Accessor<'_>,
    buffers: &[Vec<u8>],
    size: usize,
    decode: impl Fn(&[u8]) -> T,
) -> Result<Vec<T>, String> {
    let i = accessor.index();
    let count = accessor.count();
    let mut out = match accessor.view() {
        Some(view) => {
            let data = view_bytes(&view, buffers).map_err(|e| format!("accessor {i}: {e}"))?;
            let stride = view.stride().unwrap_or(size);
            if stride < size {
                return Err(format!(
                    "accessor {i}: byteStride {stride} of buffer view {} is shorter than its \
                     {size}-byte elements",
                    view.index()
                ));
            }
            let within = strided_range(accessor.offset(), stride, size, count)
                .filter(|&(_, end)| end <= data.len());
            let Some((start, _)) = within else {
                return Err(format!(
                    "accessor {i}: {count} elements of {size} bytes (stride {stride}) from byte \
                     {} run past the {} bytes of buffer view {}",
                    accessor.offset(),
                    data.len(),
                    view.index()
                ));
            };
            (0..count)
                .map(|k| {
                    let at = start + k * stride;
                    decode(&data[at..at + size])
                })
                .collect()
        }
        None if count > MAX_UNBACKED_ELEMENTS => {
            return Err(format!(
                "accessor {i} has no buffer view and {count} elements; vtq reads at most \
                 {MAX_UNBACKED_ELEMENTS} elements without a buffer view"
            ))
        }
        None => vec![T::default(); count],
    };
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        let indices = sparse.indices();
        let index_size = match indices.index_type() {
            IndexType::U8 => 1,
            IndexType::U16 => 2,
            IndexType::U32 => 4,
        };
        let index_view = indices.view();
        let index_data =
            view_bytes(&index_view, buffers).map_err(|e| format!("accessor {i} sparse: {e}"))?;
        let value_view = sparse.values().view();
        let value_data =
            view_bytes(&value_view, buffers).map_err(|e| format!("accessor {i} sparse: {e}"))?;
        let index_start = strided_range(indices.offset(), index_size, index_size, n)
            .filter(|&(_, end)| end <= index_data.len());
        let value_start = strided_range(sparse.values().offset(), size, size, n)
            .filter(|&(_, end)| end <= value_data.len());
        let (Some((index_start, _)), Some((value_start, _))) = (index_start, value_start) else {
            return Err(format!(
                "accessor {i}: its {n} sparse indices or values run past their buffer view"
            ));
        };
        for k in 0..n {
            let at = index_start + k * index_size;
            let bytes = &index_data[at..at + index_size];
            let target = match index_size {
                1 => usize::from(bytes[0]),
                2 => usize::from(u16_at(bytes, 0)),
                _ => u32_at(bytes, 0) as usize,
            };
            let slot = out.get_mut(target).ok_or_else(|| {
                format!("accessor {i}: sparse index {target} is beyond its {count} elements")
            })?;
            let at = value_start + k * size;
            *slot = decode(&value_data[at..at + size]);
        }
    }
    Ok(out)
}

/// The bytes of buffer view `view` within its buffer.
fn view_bytes<'b>(
    view: &::gltf::buffer::View<'_>,
    buffers: &'b [Vec<u8>],
) -> Result<&'b [u8], String> {
    let buffer = buffers
        .get(view.buffer().index())
        .ok_or_else(|| format!("buffer view {} names a missing buffer", view.index()))?;
    view.offset()
        .checked_add(view.length())
        .and_then(|end| buffer.get(view.offset()..end))
        .ok_or_else(|| {
            format!(
                "buffer view {} ({} bytes from byte {}) runs past the {} bytes of buffer {}",
                view.index(),
                view.length(),
                view.offset(),
                buffer.len(),
                view.buffer().index()
            )
        })
}

/// `(start, end)` of `count` elements of `size` bytes, `stride` apart, from byte `offset`
/// (`None` on overflow); `(offset, offset)` when `count` is 0.
fn strided_range(
    offset: usize,
    stride: usize,
    size: usize,
    count: usize,
) -> Option<(usize, usize)> {
    if count == 0 {
        return Some((offset, offset));
    }
    let end = stride
        .checked_mul(count - 1)?
        .checked_add(size)?
        .checked_add(offset)?;
    Some((offset, end))
}

/// The name glTF gives an accessor type.
fn dimensions_name(dimensions: Dimensions) -> &'static str {
    match dimensions {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

/// The name glTF gives a component type.
fn type_name(data_type: DataType) -> &'static str {
    match data_type {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

/// The little-endian `f32` at `at` in `b`.
fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

/// The little-endian `u32` at `at` in `b`.
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// The little-endian `u16` at `at` in `b`.
fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strided_ranges_check_overflow() {
        assert_eq!(strided_range(4, 12, 12, 0), Some((4, 4)));
        assert_eq!(strided_range(4, 16, 12, 3), Some((4, 48)));
        assert_eq!(strided_range(1, usize::MAX, 12, 3), None);
        assert_eq!(strided_range(usize::MAX, 4, 4, 1), None);
    }
}
