// MCAP chunk codecs, one place for the recorder, the player and the checks:
//   zstd: @foxglove/wasm-zstd (compresses and decompresses);
//   lz4:  @foxglove/wasm-lz4 decompresses (the codec the MCAP libraries read lz4 chunks
//         with: @mcap/support's decompress handlers), and lz4js compresses (LZ4 frame
//         format, as MCAP's lz4 chunks are; @foxglove/wasm-lz4 only decompresses).
import zstd from '@foxglove/wasm-zstd';
import lz4Decompress from '@foxglove/wasm-lz4';
import lz4js from 'lz4js';

export const kCompressions = ['zstd', 'lz4', 'none'];

// The handlers @mcap/core's readers take ({zstd, lz4}: (data, size) => bytes).
export async function decompressHandlers() {
  await Promise.all([zstd.isLoaded, lz4Decompress.isLoaded]);
  return {
    zstd: (data, size) => zstd.decompress(data, Number(size)),
    lz4: (data, size) => lz4Decompress(data, Number(size)),
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
