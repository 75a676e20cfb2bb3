"""Reads what test_dist.py checks of a 64-bit Mach-O shared library (the macOS binaries), without Apple's tools:
the header, the libraries it loads, the minimum macOS version, the symbols it exports (the export trie dyld
reads) and its code signature, whose page hashes are recomputed here as macOS does when it maps the pages.
"""
import hashlib
import struct

MH_MAGIC_64 = 0xFEEDFACF
MH_DYLIB = 6
CPU_TYPES = {0x01000007: "x86_64", 0x0100000C: "arm64"}
LC_SEGMENT_64, LC_LOAD_DYLIB, LC_CODE_SIGNATURE = 0x19, 0xC, 0x1D
LC_DYLD_INFO_ONLY, LC_DYLD_EXPORTS_TRIE = 0x80000022, 0x80000033
LC_BUILD_VERSION, LC_VERSION_MIN_MACOSX = 0x32, 0x24
CSMAGIC_EMBEDDED_SIGNATURE, CSMAGIC_CODEDIRECTORY = 0xFADE0CC0, 0xFADE0C02
CS_ADHOC, CS_HASHTYPE_SHA256 = 0x2, 2


class MachO:
    def __init__(self, data):
        self.data = data
        magic, cpu, _, filetype, ncmds, _, self.flags, _ = struct.unpack_from("<8I", data)
        if magic != MH_MAGIC_64:
            raise ValueError(f"not a 64-bit little-endian Mach-O file (magic {magic:#x})")
        self.arch = CPU_TYPES.get(cpu, hex(cpu))
        self.filetype = filetype
        self.commands = []  # (cmd, offset of the command in the file)
        off = 32
        for _ in range(ncmds):
            cmd, size = struct.unpack_from("<2I", data, off)
            self.commands.append((cmd, off))
            off += size

    def command(self, cmd):
        found = [off for c, off in self.commands if c == cmd]
        return found[0] if found else None

    def segments(self):
        return [self.data[off + 8:off + 24].rstrip(b"\0").decode() for c, off in self.commands if c == LC_SEGMENT_64]

    def dylibs(self):
        """Install names of the libraries it loads."""
        names = []
        for c, off in self.commands:
            if c == LC_LOAD_DYLIB:
                name_off = struct.unpack_from("<I", self.data, off + 8)[0]
                names.append(self.data[off + name_off:].split(b"\0", 1)[0].decode())
        return names

    def min_macos(self):
        """The minimum macOS version as (major, minor): LC_BUILD_VERSION, or LC_VERSION_MIN_MACOSX (before 10.14)."""
        off = self.command(LC_BUILD_VERSION)
        if off is not None:
            platform, minos = struct.unpack_from("<2I", self.data, off + 8)
            assert platform == 1, f"platform {platform} is not macOS"
        else:
            minos = struct.unpack_from("<I", self.data, self.command(LC_VERSION_MIN_MACOSX) + 8)[0]
        return minos >> 16, (minos >> 8) & 0xFF

    def exports(self):
        """Names of the exported symbols, from the export trie."""
        off = self.command(LC_DYLD_EXPORTS_TRIE)
        if off is not None:
            start, size = struct.unpack_from("<2I", self.data, off + 8)
        else:
            start, size = struct.unpack_from("<2I", self.data, self.command(LC_DYLD_INFO_ONLY) + 40)
        trie = self.data[start:start + size]
        names, stack = [], [(0, b"")]
        while stack:
            node, prefix = stack.pop()
            terminal, pos = uleb(trie, node)
            if terminal:
                names.append(prefix.decode())
            pos += terminal
            children = trie[pos]
            pos += 1
            for _ in range(children):
                end = trie.index(b"\0", pos)
                label = trie[pos:end]
                child, pos = uleb(trie, end + 1)
                stack.append((child, prefix + label))
        return names

    def code_signature(self):
        """(flags, hash type, pages checked, pages whose hash differs) of the embedded code signature."""
        off = self.command(LC_CODE_SIGNATURE)
        if off is None:
            return None
        sig_off, _ = struct.unpack_from("<2I", self.data, off + 8)
        magic, _, count = struct.unpack_from(">3I", self.data, sig_off)
        assert magic == CSMAGIC_EMBEDDED_SIGNATURE, hex(magic)
        for i in range(count):
            _, blob = struct.unpack_from(">2I", self.data, sig_off + 12 + 8 * i)
            cd = sig_off + blob
            if struct.unpack_from(">I", self.data, cd)[0] == CSMAGIC_CODEDIRECTORY:
                return self._check_pages(cd, sig_off)
        raise ValueError("the code signature has no code directory")

    def _check_pages(self, cd, sig_off):
        (_, _, _, flags, hash_off, _, _, n_code, code_limit, hash_size, hash_type, _, page_shift) = struct.unpack_from(
            ">9I4B", self.data, cd)
        assert code_limit == sig_off, "the signature covers the whole file before it"
        page = 1 << page_shift
        assert n_code == -(-code_limit // page), "one hash per page up to the signature"
        bad = 0
        for i in range(n_code):
            chunk = self.data[i * page:min((i + 1) * page, code_limit)]
            want = self.data[cd + hash_off + i * hash_size:cd + hash_off + (i + 1) * hash_size]
            bad += hashlib.sha256(chunk).digest()[:hash_size] != want
        return flags, hash_type, n_code, bad


def uleb(data, pos):
    """An unsigned LEB128 number at pos: (value, position after it)."""
    value = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, pos
