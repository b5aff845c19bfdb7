// Minimal ELF32 little-endian reader: the loadable segments (at their physical addresses) and
// the symbol table, which is all the rig needs of a firmware image.
import { readFileSync } from 'node:fs';

export function readElf(path) {
  const buf = readFileSync(path);
  const v = new DataView(buf.buffer, buf.byteOffset, buf.byteLength);
  if (v.getUint32(0, false) !== 0x7f454c46 || buf[4] !== 1 || buf[5] !== 1) {
    throw new Error(`${path}: not a 32-bit little-endian ELF file`);
  }
  const u16 = (o) => v.getUint16(o, true);
  const u32 = (o) => v.getUint32(o, true);
  const phoff = u32(0x1c), shoff = u32(0x20);
  const phentsize = u16(0x2a), phnum = u16(0x2c), shentsize = u16(0x2e), shnum = u16(0x30);
  const segments = [];
  for (let i = 0; i < phnum; i++) {
    const o = phoff + i * phentsize;
    const type = u32(o), offset = u32(o + 4), paddr = u32(o + 12), filesz = u32(o + 16);
    if (type === 1 && filesz > 0) segments.push({ paddr, data: buf.subarray(offset, offset + filesz) });
  }
  const sections = [];
  for (let i = 0; i < shnum; i++) {
    const o = shoff + i * shentsize;
    sections.push({ type: u32(o + 4), addr: u32(o + 12), offset: u32(o + 16), size: u32(o + 20), link: u32(o + 24), entsize: u32(o + 36) });
  }
  const symbols = new Map();
  for (const s of sections) {
    if (s.type !== 2) continue; // SHT_SYMTAB
    const strtab = sections[s.link];
    for (let o = s.offset; o < s.offset + s.size; o += 16) {
      const nameOff = u32(o);
      if (!nameOff) continue;
      let end = strtab.offset + nameOff;
      while (buf[end]) end++;
      const name = buf.toString('latin1', strtab.offset + nameOff, end);
      symbols.set(name, { value: u32(o + 4), size: u32(o + 8) });
    }
  }
  return { path, segments, symbols };
}
