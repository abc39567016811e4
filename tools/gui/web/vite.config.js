// Builds the dashboard into dist/, which rack-gui serves. Everything is bundled:
// a robot's network has no internet, so nothing may load from elsewhere at run time.
import { defineConfig } from 'vite';

export default defineConfig({
  base: './',
  build: { outDir: 'dist', emptyOutDir: true, assetsInlineLimit: 0, sourcemap: false },
});
