// The fuzzers' random numbers: a small deterministic generator (mulberry32), so that a
// seed repeats a run (mcap_fuzz.mjs, ws_client_fuzz.mjs).
export function seededRandom(seed) {
  let state = seed >>> 0;
  const rand = () => {
    state = (state + 0x6d2b79f5) >>> 0;
    let t = state;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
  const below = (n) => Math.floor(rand() * n);
  const pick = (a) => a[below(a.length)];
  return { rand, below, pick };
}
