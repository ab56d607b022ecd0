// Shared helpers of the JS protocol tests: the golden vectors (tests/protocol/vectors/vectors.json)
// and hex conversion. Paths are resolved from this file, so the tests run from any directory.
import { readFileSync } from "node:fs";

export const vectors = JSON.parse(readFileSync(new URL("../vectors/vectors.json", import.meta.url), "utf8"));

export const protocolMarkdown = readFileSync(new URL("../../../protocol/PROTOCOL.md", import.meta.url), "utf8");

// Lower-case or upper-case hex, two digits per byte, to a new Uint8Array.
export function fromHex(hex) {
  if (hex.length % 2 !== 0) throw new Error(`odd hex length ${hex.length}`);
  const out = new Uint8Array(hex.length / 2);
  for (let i = 0; i < out.length; ++i) out[i] = parseInt(hex.slice(2 * i, 2 * i + 2), 16);
  return out;
}

// A deterministic pseudo-random generator (mulberry32): uniform floats in [0, 1).
export function random(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}
