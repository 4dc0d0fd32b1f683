// How every browser page of the package's harnesses, whatever its engine, moves bytes in
// (fetchBytes) and hands binary results to Node (toBase64).

/**
 * The bytes of `view` as base64 (how a page hands binary results to the harness).
 * @param {ArrayBufferView} view
 */
export function toBase64(view) {
    const bytes = new Uint8Array(view.buffer, view.byteOffset, view.byteLength);
    let s = '';
    for (let i = 0; i < bytes.length; i += 0x8000) {
        s += String.fromCharCode.apply(null, /** @type {any} */ (bytes.subarray(i, i + 0x8000)));
    }
    return btoa(s);
}

/**
 * The bytes at `url` (an error naming the URL and the HTTP status when it fails).
 * @param {string} url
 */
export async function fetchBytes(url) {
    const response = await fetch(url);
    if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
    return new Uint8Array(await response.arrayBuffer());
}
