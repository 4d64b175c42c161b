//! The `texsyn` command line: a thin layer over the library (see `cli/mod.rs`).

mod cli;

fn main() -> std::process::ExitCode {
    tune_allocator();
    cli::main()
}

/// glibc's malloc gives every block of 128 KiB or more back to the system when it is freed, and
/// maps it again, a page fault per page, when the next one is asked for: the searches' work
/// arrays and ΣS² maps of a megabyte or more came and went per block, and a 512² inpainting
/// spent about a tenth of its time in page faults. Kept in the heap (up to 32 MiB a block),
/// freed memory is reused at once. The heap is trimmed once 32 MiB lie free at its top: glibc
/// applies the same threshold to every thread's arena, and at 128 MiB no thread's arena ever gave
/// anything back (a 1024² quilting of a 12 MP photo on 16 threads peaked 40 % above its live
/// heap); at 32 MiB the 512² inpainting takes 2 % more page faults and no measurable time.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn tune_allocator() {
    // SAFETY: `mallopt` only sets the allocator's parameters; it runs before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 32 << 20);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn tune_allocator() {}
