//! C strings, arrays and output parameters across the boundary: names in (NUL-terminated
//! UTF-8), arrays in (borrowed for the call), text out (into the caller's buffer, or as a
//! library-owned string freed by [`ay_string_free`]).

use std::ffi::{c_char, CStr, CString};

use crate::status::{ay_status, boundary, Fail};

/// Borrow a NUL-terminated UTF-8 string from C. NULL is `AY_ERR_NULL`, bad UTF-8
/// `AY_ERR_INVALID`.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that outlives `'a`.
pub(crate) unsafe fn text<'a>(p: *const c_char, what: &str) -> Result<&'a str, Fail> {
    if p.is_null() {
        return Err(Fail::null(what));
    }
    // SAFETY: non-null, and the caller promises a NUL-terminated string that outlives 'a.
    let s = unsafe { CStr::from_ptr(p) };
    s.to_str().map_err(|_| Fail::invalid(format!("{what} is not UTF-8")))
}

/// Borrow `length` items from C (NULL is allowed only with length 0).
///
/// # Safety
/// `p` is NULL or valid for `length` reads that outlive `'a`.
pub(crate) unsafe fn slice<'a, T>(p: *const T, length: usize, what: &str) -> Result<&'a [T], Fail> {
    if length == 0 {
        return Ok(&[]);
    }
    if p.is_null() {
        return Err(Fail::null(what));
    }
    // SAFETY: non-null and valid for `length` reads (caller's promise).
    Ok(unsafe { std::slice::from_raw_parts(p, length) })
}

/// Store `value` through an output pointer; NULL is `AY_ERR_NULL`.
///
/// # Safety
/// `p` is NULL or valid for a write of `T`.
pub(crate) unsafe fn put<T>(p: *mut T, value: T, what: &str) -> Result<(), Fail> {
    if p.is_null() {
        return Err(Fail::null(what));
    }
    // SAFETY: non-null and, by the caller's promise, valid for a write of T.
    unsafe { p.write(value) };
    Ok(())
}

/// Store `value` through an output pointer that may be NULL (then nothing is stored).
///
/// # Safety
/// `p` is NULL or valid for a write of `T`.
pub(crate) unsafe fn put_optional<T>(p: *mut T, value: T) {
    if !p.is_null() {
        // SAFETY: non-null and, by the caller's promise, valid for a write of T.
        unsafe { p.write(value) };
    }
}

/// Copy `items` into the caller's array of `capacity` elements, storing the count in
/// `*length` (when not NULL) whether or not it fits. `terminate` adds a zero element after
/// the items (a C string's NUL). Too small: `AY_ERR_BUFFER` (nothing copied); `buffer` may be
/// NULL when `capacity` is 0, to ask for the length.
///
/// # Safety
/// `buffer` is NULL or valid for `capacity` writes of `T`; `length` is NULL or valid.
pub(crate) unsafe fn copy_out<T: Copy + Default>(
    items: &[T],
    terminate: bool,
    buffer: *mut T,
    capacity: usize,
    length: *mut usize,
) -> Result<(), Fail> {
    // SAFETY: forwarded promise on `length`.
    unsafe { put_optional(length, items.len()) };
    let needed = items.len() + usize::from(terminate);
    if capacity < needed {
        return Err(Fail::new(
            ay_status::AY_ERR_BUFFER,
            format!("the buffer holds {capacity}, {needed} needed (the length is stored in the length output)"),
        ));
    }
    if buffer.is_null() {
        return Err(Fail::null("buffer"));
    }
    // SAFETY: buffer is valid for `capacity >= needed` writes (caller's promise), and `items`
    // cannot overlap it (it is Rust-owned memory).
    unsafe {
        std::ptr::copy_nonoverlapping(items.as_ptr(), buffer, items.len());
        if terminate {
            buffer.add(items.len()).write(T::default());
        }
    }
    Ok(())
}

/// Hand a Rust string to C as a library-owned string (free it with [`ay_string_free`]).
pub(crate) fn owned(s: String) -> *mut c_char {
    CString::new(s.replace('\0', "\\0")).unwrap_or_default().into_raw()
}

/// Free a string the library returned (the JSON reports). NULL is accepted and ignored (like
/// `free`), so a report that failed can be freed without a check.
///
/// Ownership: takes the string back; the pointer is invalid afterwards. Thread-safety: any
/// thread. Errors: none detectable — a pointer the library did not return is undefined
/// behavior, as with `free`.
///
/// # Safety
/// `s` is NULL or a string returned by this library and not freed yet.
#[no_mangle]
pub unsafe extern "C" fn ay_string_free(s: *mut c_char) -> ay_status {
    boundary("ay_string_free", || {
        if !s.is_null() {
            // SAFETY: the caller promises `s` came from CString::into_raw in `owned` and was
            // not freed yet.
            drop(unsafe { CString::from_raw(s) });
        }
        Ok(())
    })
}
