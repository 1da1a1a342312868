//! The `vtq` binary runs on a bare node: it links no library beyond the C runtime (no
//! fontconfig, freetype, libpng, zlib or brotli) and names none that it could load at run
//! time, and its charts carry text drawn from the embedded font with fontconfig pointed at an
//! empty configuration.

mod common;

use std::process::Command;

/// The libraries a Rust binary for the GNU C library may need: the C runtime only.
const C_RUNTIME: [&str; 8] = [
    "libc.so",
    "libm.so",
    "libgcc_s.so",
    "libpthread.so",
    "libdl.so",
    "librt.so",
    "libutil.so",
    "ld-linux",
];

/// The libraries the charts used to link or load.
const FORBIDDEN: [&str; 6] = [
    "libfontconfig",
    "libfreetype",
    "libpng16",
    "libbrotli",
    "libz.so",
    "libexpat",
];

fn u16_at(b: &[u8], at: usize) -> usize {
    u16::from_le_bytes(b[at..at + 2].try_into().unwrap()) as usize
}
fn u32_at(b: &[u8], at: usize) -> usize {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap()) as usize
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

/// The `DT_NEEDED` entries of a little-endian ELF64 file (empty for a static binary).
fn needed_libraries(elf: &[u8]) -> Vec<String> {
    assert_eq!(&elf[..4], b"\x7fELF", "an ELF file");
    assert_eq!(elf[4], 2, "ELF64");
    assert_eq!(elf[5], 1, "little-endian");
    let shoff = u64_at(elf, 0x28) as usize;
    let shentsize = u16_at(elf, 0x3a);
    let shnum = u16_at(elf, 0x3c);
    let section = |i: usize| elf[shoff + i * shentsize..][..shentsize].to_vec();
    let mut needed = Vec::new();
    for i in 0..shnum {
        let sh = section(i);
        // SHT_DYNAMIC; its sh_link is the string table of the names.
        if u32_at(&sh, 4) != 6 {
            continue;
        }
        let (offset, size, entsize) = (
            u64_at(&sh, 0x18) as usize,
            u64_at(&sh, 0x20) as usize,
            u64_at(&sh, 0x38) as usize,
        );
        let strtab = section(u32_at(&sh, 0x28));
        let str_offset = u64_at(&strtab, 0x18) as usize;
        for entry in elf[offset..offset + size].chunks(entsize.max(16)) {
            let (tag, value) = (u64_at(entry, 0), u64_at(entry, 8) as usize);
            if tag == 0 {
                break;
            }
            if tag == 1 {
                let name = &elf[str_offset + value..];
                let end = name.iter().position(|&c| c == 0).unwrap();
                needed.push(String::from_utf8_lossy(&name[..end]).into_owned());
            }
        }
    }
    needed
}

#[test]
fn the_binary_needs_only_the_c_runtime() {
    let exe = env!("CARGO_BIN_EXE_vtq");
    let bytes = std::fs::read(exe).unwrap();
    let needed = needed_libraries(&bytes);
    for lib in &needed {
        assert!(
            C_RUNTIME.iter().any(|c| lib.starts_with(c)),
            "vtq links {lib} (all: {needed:?}); a bare node has only the C runtime"
        );
    }
    // Nor can it load one at run time: no library name to hand to dlopen is in the binary.
    for name in FORBIDDEN {
        let found = bytes.windows(name.len()).any(|w| w == name.as_bytes());
        assert!(!found, "vtq names {name}: it could load it at run time");
    }
    if let Ok(ldd) = Command::new("ldd").arg(exe).output() {
        let text = String::from_utf8_lossy(&ldd.stdout);
        for name in FORBIDDEN {
            assert!(!text.contains(name), "ldd {exe}: {text}");
        }
    }
}

#[test]
fn the_elf_reader_finds_needed_libraries() {
    // Guards the test above against a reader that finds nothing: the test binary itself is
    // dynamically linked against the C library.
    let me = std::env::current_exe().unwrap();
    let needed = needed_libraries(&std::fs::read(me).unwrap());
    assert!(
        needed.iter().any(|l| l.starts_with("libc.so")),
        "{needed:?}"
    );
}

#[test]
fn accuracy_draws_its_chart_text_without_fontconfig() {
    let dir = common::fresh_dir("self-contained");
    let out = dir.join("acc");
    let args = common::small_accuracy_args("wknd", Some("baseline,vtq"), out.to_str().unwrap());
    common::ok_stdout(&args, common::vtq_cli_without_fonts(&dir, &args));
    let png = out.join("accuracy.png");
    // The title sits in the top 40 rows above the legend and the plot (white without text);
    // the x axis' caption in the bottom rows, under its tick labels.
    let title = common::dark_pixels(&png, 0..40);
    assert!(
        title > 200,
        "{title} dark pixels in the title band: no text drawn"
    );
    let caption = common::dark_pixels(&png, 575..600);
    assert!(
        caption > 100,
        "{caption} dark pixels in the x axis caption's band: no text drawn"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
