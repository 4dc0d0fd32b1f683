#!/usr/bin/env node
// Validate a glTF asset (.glb or .gltf) with the Khronos glTF-Validator.
//
// Usage: node validate_gltf.mjs FILE [--json]
//
// The validator is run with maxIssues 0 (no limit) and an
// externalResourceFunction that refuses every external resource, so only
// self-contained assets (GLB binary chunk, data: URIs) validate cleanly; a
// reference to an external file shows up as an error in the report.
//
// glTF-Validator 2.0.0-dev.3.10 does not know KHR_gaussian_splatting
// (KhronosGroup/glTF-Validator#252).  It reports every attribute named
// "KHR_gaussian_splatting:..." as an Error MESH_PRIMITIVE_INVALID_ATTRIBUTE
// and the extension itself as an Information UNSUPPORTED_EXTENSION.  This
// script counts, besides the validator's own totals, `numUnexpectedErrors`:
// the errors left after dropping MESH_PRIMITIVE_INVALID_ATTRIBUTE errors
// whose attribute is a valid KHR_gaussian_splatting semantic: ROTATION,
// SCALE, OPACITY, or SH_DEGREE_l_COEF_n with 0 <= l <= 3 and 0 <= n <= 2l.
// Any other attribute name still counts.  Such dropped messages carry
// "expectedKhrAttribute": true.
//
// Output with --json (stdout, one JSON object):
//   {file, validatorVersion, mimeType,
//    numErrors, numWarnings, numInfos, numHints,      (validator's totals)
//    numUnexpectedErrors, numExpectedKhrAttributeErrors,
//    truncated,                                        (validator's flag)
//    messages: [{code, severity, pointer, message, expectedKhrAttribute}]}
// with severity one of "Error", "Warning", "Information", "Hint", and
// pointer null for issues without a JSON pointer (for GLB issues the byte
// offset is given as "offset").  Without --json a readable summary is
// printed instead.
//
// Exit status: 0 when the asset was validated and numUnexpectedErrors is 0,
// 1 when it was validated and numUnexpectedErrors > 0, 2 when it could not
// be validated at all (unreadable file, undetectable format, bad usage).

import fs from 'node:fs';
import path from 'node:path';
import validator from 'gltf-validator';

const SEVERITY = ['Error', 'Warning', 'Information', 'Hint'];
const KHR_PREFIX = 'KHR_gaussian_splatting:';
const ATTRIBUTES_POINTER = /^\/meshes\/\d+\/primitives\/\d+\/attributes\/([^/]*)$/;

const fail = (msg) => {
    process.stderr.write(`validate_gltf: ${msg}\n`);
    process.exit(2);
};

// RFC 6901 reference token -> string.
const unescapePointerToken = (token) => token.replace(/~1/g, '/').replace(/~0/g, '~');

/** True when `name` is a semantic defined by KHR_gaussian_splatting. */
const isKhrGaussianSplattingSemantic = (name) => {
    if (!name.startsWith(KHR_PREFIX)) return false;
    const semantic = name.slice(KHR_PREFIX.length);
    if (semantic === 'ROTATION' || semantic === 'SCALE' || semantic === 'OPACITY') return true;
    const m = /^SH_DEGREE_(0|[1-9][0-9]*)_COEF_(0|[1-9][0-9]*)$/.exec(semantic);
    if (!m) return false;
    const l = Number(m[1]);
    const n = Number(m[2]);
    return l <= 3 && n <= 2 * l;
};

const isExpectedKhrAttributeError = (msg) => {
    if (msg.severity !== 0 || msg.code !== 'MESH_PRIMITIVE_INVALID_ATTRIBUTE') return false;
    const m = ATTRIBUTES_POINTER.exec(msg.pointer ?? '');
    return !!m && isKhrGaussianSplattingSemantic(unescapePointerToken(m[1]));
};

const main = async () => {
    const args = process.argv.slice(2);
    const json = args.includes('--json');
    const files = args.filter((a) => a !== '--json');
    if (files.length !== 1 || files[0].startsWith('-')) {
        fail('usage: node validate_gltf.mjs FILE [--json]');
    }
    const file = files[0];
    let bytes;
    try {
        bytes = fs.readFileSync(file);
    } catch (e) {
        fail(`cannot read ${file}: ${e.message}`);
    }
    let report;
    try {
        report = await validator.validateBytes(new Uint8Array(bytes), {
            uri: path.basename(file),
            maxIssues: 0,
            writeTimestamp: false,
            externalResourceFunction: (uri) => Promise.reject(new Error(`external resource refused: ${uri}`))
        });
    } catch (e) {
        fail(`${file}: the validator could not process the asset: ${e?.message ?? e}`);
    }

    const issues = report.issues;
    const messages = issues.messages.map((m) => {
        const out = {
            code: m.code,
            severity: SEVERITY[m.severity] ?? String(m.severity),
            pointer: m.pointer ?? null,
            message: m.message,
            expectedKhrAttribute: isExpectedKhrAttributeError(m)
        };
        if (m.offset !== undefined) out.offset = m.offset;
        return out;
    });
    const numExpected = messages.filter((m) => m.expectedKhrAttribute).length;
    const result = {
        file,
        validatorVersion: report.validatorVersion,
        mimeType: report.mimeType ?? null,
        numErrors: issues.numErrors,
        numWarnings: issues.numWarnings,
        numInfos: issues.numInfos,
        numHints: issues.numHints,
        numUnexpectedErrors: issues.numErrors - numExpected,
        numExpectedKhrAttributeErrors: numExpected,
        truncated: !!issues.truncated,
        messages
    };

    if (json) {
        process.stdout.write(`${JSON.stringify(result)}\n`);
    } else {
        const lines = [
            `${file}: glTF-Validator ${result.validatorVersion}`,
            `errors ${result.numErrors} (unexpected ${result.numUnexpectedErrors}, ` +
                `KHR_gaussian_splatting attributes ${numExpected}), warnings ${result.numWarnings}, ` +
                `infos ${result.numInfos}, hints ${result.numHints}`
        ];
        for (const m of messages) {
            const where = m.pointer ?? (m.offset !== undefined ? `@${m.offset}` : '');
            const tag = m.expectedKhrAttribute ? ' [expected: KHR_gaussian_splatting]' : '';
            lines.push(`  ${m.severity} ${m.code} ${where}: ${m.message}${tag}`);
        }
        process.stdout.write(`${lines.join('\n')}\n`);
    }
    process.exitCode = result.numUnexpectedErrors > 0 ? 1 : 0;
};

main().catch((e) => fail(e?.stack ?? String(e)));
