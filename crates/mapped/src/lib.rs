//! # coupler-mapped
//!
//! A read-only memory map of a whole file, as a byte slice: what lets `search` scan the
//! columns of a million-curve index without reading them into memory (the pages the
//! scan touches are the page cache's, shared, and not the process's own memory).
//!
//! This is the workspace's one use of `unsafe` (the rest of the workspace forbids it).
//! What the caller must know, and what makes it sound enough to use:
//!
//! - The bytes are the file's as the kernel pages them in: a file changed in place by
//!   another process while it is mapped can change under the slice, and one **cut short**
//!   in place makes a read past its new end raise `SIGBUS` (the process stops). The
//!   program never changes such files in place (it writes a new file and renames it over
//!   the old one, which leaves a reader's mapping intact), so this happens only to a file
//!   another program truncates while a search runs. Callers treat the bytes as untrusted
//!   input (every length, offset and checksum is checked before use), so changed bytes
//!   give an error or a rebuild, never undefined values.
//! - On platforms without `mmap` (not unix), the file is read into memory instead.

use std::fs::File;

/// A whole file mapped read-only (or, off unix, read into memory).
pub struct Mapped {
    inner: Inner,
}

enum Inner {
    Empty,
    #[cfg(unix)]
    Map {
        ptr: *mut std::ffi::c_void,
        len: usize,
    },
    #[cfg(not(unix))]
    Owned(Vec<u8>),
}

// SAFETY: the mapping is read-only and private to this value; sharing a `&[u8]` to it
// between threads is like sharing any immutable buffer.
#[allow(unsafe_code)]
unsafe impl Send for Mapped {}
// SAFETY: as above: no interior mutability.
#[allow(unsafe_code)]
unsafe impl Sync for Mapped {}

impl Mapped {
    /// Maps all of `file` (its length as `fstat` reports it now) read-only.
    pub fn of_file(file: &File) -> std::io::Result<Mapped> {
        let len = file.metadata()?.len();
        let len =
            usize::try_from(len).map_err(|_| std::io::Error::other("file too large to map"))?;
        if len == 0 {
            return Ok(Mapped {
                inner: Inner::Empty,
            });
        }
        Mapped::map(file, len)
    }

    #[cfg(unix)]
    #[allow(unsafe_code)]
    fn map(file: &File, len: usize) -> std::io::Result<Mapped> {
        use rustix::mm::{MapFlags, ProtFlags, mmap};
        // SAFETY: a new mapping (no address hint) of `len` bytes of an open file,
        // read-only and private: it aliases no memory of this process. The returned
        // pointer is valid for `len` bytes until `munmap` in `drop`.
        let ptr = unsafe {
            mmap(
                std::ptr::null_mut(),
                len,
                ProtFlags::READ,
                MapFlags::PRIVATE,
                file,
                0,
            )
        }?;
        Ok(Mapped {
            inner: Inner::Map { ptr, len },
        })
    }

    #[cfg(not(unix))]
    fn map(file: &File, len: usize) -> std::io::Result<Mapped> {
        use std::io::Read;
        let mut bytes = Vec::with_capacity(len);
        file.take(len as u64).read_to_end(&mut bytes)?;
        Ok(Mapped {
            inner: Inner::Owned(bytes),
        })
    }

    /// The mapped bytes.
    pub fn bytes(&self) -> &[u8] {
        match &self.inner {
            Inner::Empty => &[],
            #[cfg(unix)]
            #[allow(unsafe_code)]
            // SAFETY: `ptr` is a live read-only mapping of `len` bytes (see `map`),
            // unmapped only in `drop`, which needs `&mut self`; the slice borrows `self`.
            Inner::Map { ptr, len } => unsafe {
                std::slice::from_raw_parts(ptr.cast::<u8>().cast_const(), *len)
            },
            #[cfg(not(unix))]
            Inner::Owned(b) => b,
        }
    }
}

impl std::ops::Deref for Mapped {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        self.bytes()
    }
}

impl Drop for Mapped {
    fn drop(&mut self) {
        #[cfg(unix)]
        if let Inner::Map { ptr, len } = self.inner {
            // SAFETY: the mapping made in `map`, unmapped once; no slice of it outlives
            // `self` (they borrow it).
            #[allow(unsafe_code)]
            let _ = unsafe { rustix::mm::munmap(ptr, len) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn maps_a_file_and_an_empty_one() {
        let dir = std::env::temp_dir().join(format!("coupler-mapped-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("f");
        let mut f = File::create(&p).unwrap();
        let data: Vec<u8> = (0..10_000u32).map(|i| (i * 7) as u8).collect();
        f.write_all(&data).unwrap();
        drop(f);
        let m = Mapped::of_file(&File::open(&p).unwrap()).unwrap();
        assert_eq!(&*m, &data[..]);
        // Shared between threads.
        std::thread::scope(|s| {
            s.spawn(|| assert_eq!(m.len(), data.len()));
        });
        File::create(&p).unwrap();
        let e = Mapped::of_file(&File::open(&p).unwrap()).unwrap();
        assert!(e.is_empty());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
