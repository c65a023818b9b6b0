#!/usr/bin/env node
// Runs the Khronos glTF-Validator (npm package `gltf-validator`, pinned in package.json) on each
// file named on the command line and prints one JSON object per file, one per line, on stdout:
//
//   {"file", "validatorVersion", "mimeType", "numErrors", "numWarnings", "numInfos", "numHints",
//    "truncated", "messages": [{"code", "severity", "pointer", "offset", "message"}]}
//
// `severity` is "error", "warning", "info" or "hint"; `pointer` is the JSON pointer of the issue
// or null (GLB-level issues have a byte `offset` instead).
//
// A file named `-` is read from standard input (GLB or glTF JSON, detected from the first byte);
// it has no directory, so any external resource it references is refused (data: URIs still
// work: the validator decodes those itself). For a file on disk, external resources (.bin
// buffers, images) are read relative to that file's directory; a URI that resolves outside it
// is refused, and the validator reports it as an IO_ERROR.
//
// Exit status: 0 when every file was validated, whatever the reports say; 1 when a file could not
// be read or the validator could not produce a report for it (that file's line then has an
// "error" field instead of the counts); 2 on bad usage.
//
// Test-only tooling: install with scripts/install-gltf-validator.

import { readFile, realpath } from 'node:fs/promises';
import path from 'node:path';
import validator from 'gltf-validator';

const SEVERITY = ['error', 'warning', 'info', 'hint'];

function usage() {
    process.stderr.write('usage: validate.mjs FILE.glb|FILE.gltf|- ...\n');
    process.exit(2);
}

async function readStdin() {
    const chunks = [];
    for await (const chunk of process.stdin) chunks.push(chunk);
    return Buffer.concat(chunks);
}

// Whether `child` is `dir` itself or lies below it (both absolute and normalized).
function isInside(dir, child) {
    const rel = path.relative(dir, child);
    return rel === '' || (!rel.startsWith('..') && !path.isAbsolute(rel));
}

// The validator's externalResourceFunction for a file in `baseDir` (null: refuse everything).
function resourceLoader(baseDir) {
    return async (uri) => {
        if (baseDir === null) {
            throw new Error(`external resource '${uri}' refused: input from stdin has no directory`);
        }
        // A URI with a scheme (http:, file:, ...) is not a relative file reference.
        if (/^[a-zA-Z][a-zA-Z0-9+.-]*:/.test(uri)) {
            throw new Error(`external resource '${uri}' refused: not a relative path`);
        }
        let rel;
        try {
            rel = decodeURIComponent(uri);
        } catch {
            throw new Error(`external resource '${uri}' refused: malformed percent-encoding`);
        }
        if (rel.includes('\0') || path.isAbsolute(rel)) {
            throw new Error(`external resource '${uri}' refused: not a relative path`);
        }
        const target = path.resolve(baseDir, rel);
        if (!isInside(baseDir, target)) {
            throw new Error(`external resource '${uri}' refused: outside ${baseDir}`);
        }
        // Follow symlinks too: the real file must still be inside the real directory.
        const realTarget = await realpath(target);
        if (!isInside(baseDir, realTarget)) {
            throw new Error(`external resource '${uri}' refused: links outside ${baseDir}`);
        }
        return new Uint8Array(await readFile(realTarget));
    };
}

async function validateOne(file) {
    let bytes;
    let baseDir;
    if (file === '-') {
        bytes = await readStdin();
        baseDir = null;
    } else {
        bytes = await readFile(file);
        baseDir = await realpath(path.dirname(path.resolve(file)));
    }
    const report = await validator.validateBytes(new Uint8Array(bytes), {
        uri: file === '-' ? 'stdin' : path.basename(file),
        maxIssues: 0, // unlimited
        writeTimestamp: false,
        externalResourceFunction: resourceLoader(baseDir),
    });
    const issues = report.issues;
    return {
        file,
        validatorVersion: report.validatorVersion,
        mimeType: report.mimeType ?? null,
        numErrors: issues.numErrors,
        numWarnings: issues.numWarnings,
        numInfos: issues.numInfos,
        numHints: issues.numHints,
        truncated: issues.truncated,
        messages: issues.messages.map((m) => ({
            code: m.code,
            severity: SEVERITY[m.severity] ?? String(m.severity),
            pointer: m.pointer ?? null,
            offset: m.offset ?? null,
            message: m.message,
        })),
    };
}

const files = process.argv.slice(2);
if (files.length === 0 || files.some((f) => f.startsWith('-') && f !== '-')) usage();
if (files.filter((f) => f === '-').length > 1) usage();

let failed = false;
for (const file of files) {
    let line;
    try {
        line = await validateOne(file);
    } catch (err) {
        // The validator rejects with a plain string; fs errors are Error objects.
        const text = err instanceof Error ? err.message : String(err);
        process.stderr.write(`validate.mjs: ${file}: ${text}\n`);
        line = { file, error: text };
        failed = true;
    }
    process.stdout.write(JSON.stringify(line) + '\n');
}
process.exitCode = failed ? 1 : 0;
