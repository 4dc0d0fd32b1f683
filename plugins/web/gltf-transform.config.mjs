// gltf-transform CLI configuration that keeps mesh-anchored Gaussian splats anchored:
//
//     npx gltf-transform --config plugins/web/gltf-transform.config.mjs copy in.glb out.glb
//
// Registers KHR_gaussian_splatting and GSVERSE_gaussian_splatting_mesh_anchor next to the
// extensions the CLI knows. Use the CLI installed in plugins/web/node_modules (one copy of
// @gltf-transform/core for the CLI and the extensions). Operations that would change the anchor
// mesh or the splats' order refuse to write; see README.md §glTF-Transform.

import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { gsverseExtensions } from './src/gltf-transform/index.js';

export default {
    extensions: [...ALL_EXTENSIONS, ...gsverseExtensions],
    // The CLI (4.5.1) parses global options only after the command name; accept
    // `gltf-transform --config PATH COMMAND ...` too by moving the option behind the command.
    onProgramReady: async () => {
        const argv = process.argv;
        if (argv[2] === '--config') argv.push(...argv.splice(2, 2));
    },
};
