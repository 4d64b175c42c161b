//! Files whose names come from outside: bounded reads and link-refusing opens.
//!
//! A path in a job file, a manifest or an export index may name anything: `/dev/zero`, a FIFO, a
//! 100 GB file, a symlink planted in the output directory. `std::fs::read` would grow memory
//! without limit on the first and block forever on the second; `File::create` writes wherever a
//! link points. Every read of such a path goes through [`read_limited`] (a regular file, at most
//! so many bytes), and every file texsyn creates in a directory it owns goes through
//! [`create_new`] or [`open_no_follow`].

use std::fs::{File, OpenOptions};
use std::io::{self, Read};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// The largest job file read (a sweep of 100 000 points fits in a few kilobytes).
pub const MAX_JOB_FILE_BYTES: u64 = 64 << 20;
/// The largest manifest read: a merged manifest of 100 000 jobs is about 300 MB.
pub const MAX_MANIFEST_BYTES: u64 = 1 << 30;
/// The largest image file read (the decoder's own limits bound what it decodes to).
pub const MAX_IMAGE_FILE_BYTES: u64 = 1 << 30;
/// The largest small JSON document read (golden files, tile-set indexes, report listings).
pub const MAX_JSON_BYTES: u64 = 256 << 20;

/// Reads a regular file of at most `limit` bytes. Anything else (a device, a FIFO, a directory,
/// a larger file) is an error naming the reason, before any large allocation.
pub fn read_limited(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    // O_NONBLOCK: opening a FIFO with no writer must not hang; it is refused below.
    let file = OpenOptions::new().read(true).custom_flags(libc::O_NONBLOCK).open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        let what = if meta.is_dir() { "a directory" } else { "not a regular file (a device, FIFO or socket)" };
        return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("is {what}")));
    }
    if meta.len() > limit {
        return Err(too_large(meta.len(), limit));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    // One byte more than the limit: a file that grew since the size was read is caught too.
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64, limit));
    }
    Ok(bytes)
}

fn too_large(len: u64, limit: u64) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, format!("is {len} bytes or more, over the {limit}-byte limit for this kind of file"))
}

/// Creates a file that must not exist yet (`O_CREAT | O_EXCL`): a symlink or file planted at the
/// name makes it fail instead of being written through.
pub fn create_new(path: &Path) -> io::Result<File> {
    OpenOptions::new().write(true).create_new(true).open(path)
}

/// Opens (creating it if needed) a file for reading and writing without following a symlink at
/// its name, and refuses anything but a regular file with a single name: writing into a hard link
/// would change the other name's content too.
pub fn open_no_follow(path: &Path) -> io::Result<File> {
    let file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| {
            if e.raw_os_error() == Some(libc::ELOOP) {
                io::Error::new(io::ErrorKind::InvalidInput, "is a symlink; refusing to write through it")
            } else {
                e
            }
        })?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "is not a regular file; refusing to write to it"));
    }
    if std::os::unix::fs::MetadataExt::nlink(&meta) > 1 {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "has other names (a hard link); refusing to write to it"));
    }
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("texsyn-files-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn bounded_reads_refuse_devices_directories_and_large_files() {
        let d = dir("read");
        std::fs::write(d.join("small"), b"12345").unwrap();
        assert_eq!(read_limited(&d.join("small"), 5).unwrap(), b"12345");
        let e = read_limited(&d.join("small"), 4).unwrap_err();
        assert!(e.to_string().contains("over the 4-byte limit"), "{e}");
        let e = read_limited(Path::new("/dev/zero"), 1 << 20).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let e = read_limited(&d, 1 << 20).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
    }

    #[test]
    fn link_refusing_opens_refuse_symlinks_and_hard_links() {
        let d = dir("links");
        let victim = d.join("victim");
        std::fs::write(&victim, b"precious").unwrap();
        std::os::unix::fs::symlink(&victim, d.join("sym")).unwrap();
        let e = open_no_follow(&d.join("sym")).unwrap_err();
        assert!(e.to_string().contains("symlink"), "{e}");
        std::fs::hard_link(&victim, d.join("hard")).unwrap();
        let e = open_no_follow(&d.join("hard")).unwrap_err();
        assert!(e.to_string().contains("hard link"), "{e}");
        assert!(create_new(&d.join("sym")).is_err());
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(open_no_follow(&d.join("fresh")).is_ok());
    }
}
