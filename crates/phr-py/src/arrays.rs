//! numpy arrays in: `(n, 3)` float32 points read in place when they are C-contiguous, float64
//! (or strided float32) converted once; `(m, 3)` uint32 indices read in place, other integer
//! types checked and converted. Anything else is refused with a message that says what was
//! given and what is expected.

use glam::Vec3;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods};
use phr_render::scene::MAX_COORDINATE;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// `(n, 3)` float32 values, borrowed from numpy or converted.
pub enum Floats<'py> {
    Borrowed(PyReadonlyArray2<'py, f32>),
    Owned(Vec<f32>),
}

impl Floats<'_> {
    pub fn as_slice(&self) -> &[f32] {
        match self {
            // Only C-contiguous arrays are borrowed (checked when made).
            Floats::Borrowed(a) => a.as_slice().expect("contiguous"),
            Floats::Owned(v) => v,
        }
    }

    /// The rows as points (the slice reinterpreted: `Vec3` is three `f32`s).
    pub fn as_vec3s(&self) -> &[Vec3] {
        let s = self.as_slice();
        debug_assert_eq!(s.len() % 3, 0);
        // SAFETY: `Vec3` is `repr(C)` of three f32 (alignment 4, size 12), the slice's length
        // is a multiple of 3 (shape (n, 3)), and f32 slices are 4-aligned.
        unsafe { std::slice::from_raw_parts(s.as_ptr().cast::<Vec3>(), s.len() / 3) }
    }
}

/// `points` as mesh vertices: every coordinate finite and within the renderer's
/// [`MAX_COORDINATE`] (beyond it squared distances overflow f32), else a `ValueError` naming
/// the first vertex that is not.
pub fn check_vertices(points: &[Vec3]) -> PyResult<()> {
    use rayon::prelude::*;
    let bad = points.par_iter().position_first(|p| !(p.is_finite() && p.abs().max_element() <= MAX_COORDINATE));
    match bad {
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
            Indices::Borrowed(a) => a.as_slice().expect("contiguous"),
            Indices::Owned(v) => v,
        };
        // SAFETY: `[u32; 3]` has the layout of three u32; the length is a multiple of 3.
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

fn check_shape(name: &str, obj: &Bound<'_, PyAny>, shape: &[usize]) -> PyResult<()> {
    if shape.len() != 2 || shape[1] != 3 {
        return Err(PyValueError::new_err(format!("{name} must have shape (n, 3), got {}", describe(obj))));
    }
    Ok(())
}

/// `obj` as `(n, 3)` float32 values: float32 read in place when C-contiguous, float64 and
/// strided float32 converted.
pub fn floats<'py>(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<Floats<'py>> {
    if let Ok(a) = obj.cast::<PyArray2<f32>>() {
        check_shape(name, obj, a.shape())?;
        let a = a.readonly();
        return Ok(if a.is_c_contiguous() {
            Floats::Borrowed(a)
        } else {
            Floats::Owned(a.as_array().iter().copied().collect())
        });
    }
    if let Ok(a) = obj.cast::<PyArray2<f64>>() {
        check_shape(name, obj, a.shape())?;
        return Ok(Floats::Owned(a.readonly().as_array().iter().map(|&x| x as f32).collect()));
    }
    Err(PyTypeError::new_err(format!(
        "{name} must be a float32 or float64 numpy array of shape (n, 3), got {}",
        describe(obj)
    )))
}

/// `obj` as `(m, 3)` vertex indices below `vertex_count`: uint32 read in place when
/// C-contiguous, other integer types checked and converted.
pub fn indices<'py>(obj: &Bound<'py, PyAny>, vertex_count: usize) -> PyResult<Indices<'py>> {
    const NAME: &str = "indices";
    let out_of_range =
        |v: i128| PyValueError::new_err(format!("indices must lie in 0..{vertex_count} (the vertex count), found {v}"));
    let checked = |values: Vec<i128>| -> PyResult<Indices<'py>> {
        match values.iter().find(|&&v| v < 0 || v >= vertex_count as i128) {
            Some(&v) => Err(out_of_range(v)),
            None => Ok(Indices::Owned(values.into_iter().map(|v| v as u32).collect())),
        }
    };
    if let Ok(a) = obj.cast::<PyArray2<u32>>() {
        check_shape(NAME, obj, a.shape())?;
        let a = a.readonly();
        let owned;
        let values: &[u32] = if a.is_c_contiguous() {
            a.as_slice().expect("contiguous")
        } else {
            owned = a.as_array().iter().copied().collect::<Vec<_>>();
            &owned
        };
        if let Some(&v) = values.iter().find(|&&v| v as usize >= vertex_count) {
            return Err(out_of_range(v.into()));
        }
        return Ok(if a.is_c_contiguous() { Indices::Borrowed(a) } else { Indices::Owned(values.to_vec()) });
    }
    macro_rules! convert {
        ($($t:ty),*) => {$(
            if let Ok(a) = obj.cast::<PyArray2<$t>>() {
                check_shape(NAME, obj, a.shape())?;
                return checked(a.readonly().as_array().iter().map(|&v| v as i128).collect());
            }
        )*};
    }
    convert!(i64, i32, u64, i16, u16, i8, u8);
    Err(PyTypeError::new_err(format!(
        "indices must be an integer numpy array of shape (m, 3) (uint32 is read without a copy), got {}",
        describe(obj)
    )))
}
