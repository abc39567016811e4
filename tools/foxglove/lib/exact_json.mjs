// JSON without losing an integer: sample times are nanoseconds since the epoch
// (CLOCK_REALTIME, about 1.8e18), past the 2^53 a JavaScript number holds exactly, so
// JSON.parse would round them to 256 ns and a recording's log times would not be the
// recorded ones. npm's lossless-json parses the text itself: an integer that a number
// cannot hold exactly becomes a BigInt (every other number stays a number), and
// stringify writes a BigInt back as its digits.
import { isInteger, parse, stringify } from 'lossless-json';

function parseNumber(text) {
  if (isInteger(text)) {
    const n = Number(text);
    return Number.isSafeInteger(n) ? n : BigInt(text);
  }
  return Number.parseFloat(text);
}

// The value of a JSON text, its large integers as BigInts; throws on malformed text.
export function parseExact(text) {
  return parse(text, null, parseNumber);
}

// JSON text of a value that may hold BigInts (written as their digits).
export function stringifyExact(value) {
  return stringify(value);
}

// Whether v is an integer: a number or a BigInt (parseExact's large integers).
export function isInt(v) {
  return Number.isInteger(v) || typeof v === 'bigint';
}
