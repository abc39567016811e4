// MCAP chunk codecs, one place for the recorder, the player and the checks:
//   zstd: @foxglove/wasm-zstd (compresses and decompresses);
//   lz4:  @foxglove/wasm-lz4 decompresses (the codec the MCAP libraries read lz4 chunks
//         with: @mcap/support's decompress handlers), and lz4js compresses (LZ4 frame
//         format, as MCAP's lz4 chunks are; @foxglove/wasm-lz4 only decompresses).
import { createRequire } from 'node:module';

import zstd from '@foxglove/wasm-zstd';
import lz4js from 'lz4js';

export const kCompressions = ['zstd', 'lz4', 'none'];

// @foxglove/wasm-lz4 keeps one LZ4F decompression context per copy of the module and
// does not reset it after an error: every later frame failed too ("Error during
// decompression" for a good chunk read after a bad one, in the same process). After an
// error, the next decompressHandlers() loads a fresh copy (its own WebAssembly instance
// and context); the first error of a read is the one reported, with its chunk.
const require = createRequire(import.meta.url);
let lz4Decompress = require('@foxglove/wasm-lz4');
let lz4Failed = false;
function freshLz4() {
  delete require.cache[require.resolve('@foxglove/wasm-lz4')];
  return require('@foxglove/wasm-lz4');
}

// The handlers @mcap/core's readers take ({zstd, lz4}: (data, size) => bytes).
export async function decompressHandlers() {
  if (lz4Failed) {
    lz4Decompress = freshLz4();
    lz4Failed = false;
  }
  await Promise.all([zstd.isLoaded, lz4Decompress.isLoaded]);
  return {
    zstd: (data, size) => zstd.decompress(data, Number(size)),
    lz4: (data, size) => {
      try {
        return lz4Decompress(data, Number(size));
      } catch (e) {
        lz4Failed = true;
        throw e;
      }
    },
  };
}

// McapWriter's compressChunk for a compression name (undefined: chunks uncompressed).
export async function chunkCompressor(compression) {
  if (compression === 'zstd') {
    await zstd.isLoaded;
    return (data) => ({ compression: 'zstd', compressedData: zstd.compress(data, 3) });
  }
  if (compression === 'lz4') return (data) => ({ compression: 'lz4', compressedData: Uint8Array.from(lz4js.compress(data)) });
  return undefined;
}
