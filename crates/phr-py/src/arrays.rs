//! numpy arrays in: `(n, 3)` float32 points read in place when they are C-contiguous and
//! aligned, any other float array (float64, float16, strided, unaligned, other byte order)
//! converted once by numpy; `(m, 3)` uint32 indices read in place, other integer arrays
//! converted and checked. Anything else is refused with a message that says what was given
//! and what is expected.

use glam::Vec3;
use numpy::{PyArray2, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods};
use phr_render::scene::MAX_COORDINATE;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// `(n, 3)` float32 values, C-contiguous and aligned: the caller's array or numpy's
/// converted copy.
pub struct Floats<'py>(PyReadonlyArray2<'py, f32>);

impl Floats<'_> {
    pub fn as_slice(&self) -> &[f32] {
        self.0.as_slice().expect("checked contiguous and aligned when made")
    }

    /// The rows as points (the slice reinterpreted: `Vec3` is three `f32`s).
    pub fn as_vec3s(&self) -> &[Vec3] {
        let s = self.as_slice();
        debug_assert_eq!(s.len() % 3, 0);
        // SAFETY: `Vec3` is `repr(C)` of three f32 (alignment 4, size 12), the slice's length
        // is a multiple of 3 (shape (n, 3)), and the slice is aligned (numpy's `as_slice`
        // checks it).
        unsafe { std::slice::from_raw_parts(s.as_ptr().cast::<Vec3>(), s.len() / 3) }
    }
}

/// `points` as mesh vertices: every coordinate finite and within the renderer's
/// [`MAX_COORDINATE`] (beyond it squared distances overflow f32), else a `ValueError` naming
/// the first vertex that is not.
pub fn check_vertices(points: &[Vec3]) -> PyResult<()> {
    match points.iter().position(|p| !(p.is_finite() && p.abs().max_element() <= MAX_COORDINATE)) {
        Some(i) => Err(PyValueError::new_err(format!(
            "vertices[{i}] = {:?}: coordinates must be finite and at most {MAX_COORDINATE:e} in magnitude",
            points[i].to_array()
        ))),
        None => Ok(()),
    }
}

/// `(m, 3)` uint32 values, borrowed from numpy or converted.
pub enum Indices<'py> {
    Borrowed(PyReadonlyArray2<'py, u32>),
    Owned(Vec<u32>),
}

impl Indices<'_> {
    pub fn as_triples(&self) -> &[[u32; 3]] {
        let s = match self {
            Indices::Borrowed(a) => a.as_slice().expect("checked contiguous and aligned when made"),
            Indices::Owned(v) => v,
        };
        // SAFETY: `[u32; 3]` has the layout of three u32 (alignment 4); the length is a
        // multiple of 3 and the slice aligned.
        unsafe { std::slice::from_raw_parts(s.as_ptr().cast::<[u32; 3]>(), s.len() / 3) }
    }
}

/// "an array of dtype float64 and shape (10, 4)", or "a list (convert it with
/// numpy.asarray)".
fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.cast::<PyUntypedArray>() {
        Ok(a) => {
            let dims: Vec<String> = a.shape().iter().map(usize::to_string).collect();
            let comma = if dims.len() == 1 { "," } else { "" };
            format!("an array of dtype {} and shape ({}{comma})", a.dtype(), dims.join(", "))
        }
        Err(_) => {
            let name = obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into());
            format!("a {name} (convert it with numpy.asarray)")
        }
    }
}

/// `obj` as a numpy array of shape (n, 3) whose dtype is of one of `kinds` (numpy's dtype
/// kind characters), else the error saying what is `expected`.
fn array_of<'a, 'py>(
    name: &str,
    obj: &'a Bound<'py, PyAny>,
    kinds: &[u8],
    expected: &str,
) -> PyResult<&'a Bound<'py, PyUntypedArray>> {
    let refuse = || PyTypeError::new_err(format!("{name} must be {expected} of shape (n, 3), got {}", describe(obj)));
    let array = obj.cast::<PyUntypedArray>().map_err(|_| refuse())?;
    if !kinds.contains(&array.dtype().kind()) {
        return Err(refuse());
    }
    let shape = array.shape();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!("{name} must have shape (n, 3), got {}", describe(obj))));
    }
    Ok(array)
}

/// numpy's C-contiguous, aligned, native copy of `obj` as `dtype` (a no-op for an array that
/// already is one).
fn contiguous<'py, T: numpy::Element>(obj: &Bound<'py, PyAny>, dtype: &str) -> PyResult<PyReadonlyArray2<'py, T>> {
    let numpy = obj.py().import("numpy")?;
    // (`ascontiguousarray` would keep an unaligned array as it is.)
    let converted = numpy.call_method1("require", (obj, dtype, ["C_CONTIGUOUS", "ALIGNED"]))?;
    let array = converted.cast_into::<PyArray2<T>>().map_err(PyErr::from)?;
    let read = array.try_readonly().map_err(|e| PyValueError::new_err(format!("cannot read the array: {e}")))?;
    read.as_slice().map_err(|e| PyValueError::new_err(format!("cannot read the array: {e}")))?;
    Ok(read)
}

/// The array itself if it is `T`, C-contiguous (numpy's `as_slice` also takes Fortran
/// order, which would read the rows as columns), aligned and not borrowed for writing.
fn in_place<'py, T: numpy::Element>(obj: &Bound<'py, PyAny>) -> Option<PyReadonlyArray2<'py, T>> {
    let read = obj.cast::<PyArray2<T>>().ok()?.try_readonly().ok()?;
    (read.is_c_contiguous() && read.as_slice().is_ok()).then_some(read)
}

/// `obj` as `(n, 3)` float32 values: float32 read in place when C-contiguous and aligned,
/// any other float array converted.
pub fn floats<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<Floats<'py>> {
    array_of(name, obj, b"f", "a float32 or float64 numpy array")?;
    match in_place::<f32>(obj) {
        Some(read) => Ok(Floats(read)),
        None => Ok(Floats(contiguous::<f32>(obj, "float32")?)),
    }
}

/// `obj` as `(m, 3)` vertex indices below `vertex_count`: uint32 read in place when
/// C-contiguous and aligned, other integer arrays converted and checked.
pub fn indices<'py>(obj: &Bound<'py, PyAny>, vertex_count: usize) -> PyResult<Indices<'py>> {
    array_of("indices", obj, b"iu", "an integer numpy array (uint32 is read without a copy)")?;
    let out_of_range =
        |v: i64| PyValueError::new_err(format!("indices must lie in 0..{vertex_count} (the vertex count), found {v}"));
    if let Some(read) = in_place::<u32>(obj) {
        let values = read.as_slice().expect("checked by in_place");
        return match values.iter().find(|&&v| v as usize >= vertex_count) {
            Some(&v) => Err(out_of_range(v.into())),
            None => Ok(Indices::Borrowed(read)),
        };
    }
    let wide = contiguous::<i64>(obj, "int64")?;
    let values = wide.as_slice().expect("checked by contiguous");
    match values.iter().find(|&&v| v < 0 || v as u64 >= vertex_count as u64) {
        Some(&v) => Err(out_of_range(v)),
        None => Ok(Indices::Owned(values.iter().map(|&v| v as u32).collect())),
    }
}
