// Playback of an asset's own animations in the demo: an anchor mesh converted from a rigged
// character (`gsverse-convert --mesh character.glb`) keeps its skin, morph targets and
// animations; `loadAnchoredAsset` lists them and each AnchoredSplat samples them
// (`splat.animation.sample`). The player keeps which animation is chosen, its time, whether it
// plays; the panel row lets a person pick, play, pause and scrub. The physics acts on top: the
// soft body's displacement from its rest pose is added to the animated pose (DemoAsset.sync), so a
// pull, a shake or a drop moves the animated character; this is exact for translations and small
// pulls, and approximate where the animation turns a part far from its rest pose (the
// displacement keeps its rest-pose direction).

/**
 * @typedef {object} AnimationInfo
 * @property {number} index     its index in the file's `animations`
 * @property {string} name
 * @property {number} duration  s
 */

export class AnimationPlayer {
    constructor() {
        /** @type {AnimationInfo[]} */
        this.list = [];
        /** position in `list` of the chosen animation, -1: none (the rest pose) */
        this.chosen = -1;
        this.time = 0;
        this.playing = false;
        this.speed = 1;
    }

    /** @param {AnimationInfo[]} list  the loaded asset's animations */
    setAnimations(list) {
        this.list = list.slice();
        this.chosen = -1;
        this.time = 0;
        this.playing = false;
    }

    /** The chosen animation, or null. */
    get current() {
        return this.chosen >= 0 ? this.list[this.chosen] : null;
    }

    /**
     * Choose an animation by its position in `list` (-1: none, back to the rest pose).
     * @param {number} i
     */
    choose(i) {
        if (!(Number.isInteger(i) && i >= -1 && i < this.list.length)) {
            throw new RangeError(`animation ${i}: the asset has ${this.list.length} (use -1 for none)`);
        }
        this.chosen = i;
        this.time = 0;
        if (i < 0) this.playing = false;
    }

    /** @param {number} t seconds, clamped to the animation's keys */
    seek(t) {
        const a = this.current;
        if (!a || !Number.isFinite(t)) return;
        this.time = Math.min(Math.max(0, t), a.duration);
    }

    /**
     * Advance a playing animation by `dt` seconds (looping); true when the pose changed.
     * @param {number} dt
     */
    advance(dt) {
        const a = this.current;
        if (!a || !this.playing) return false;
        this.time = a.duration > 0 ? (this.time + this.speed * dt) % a.duration : 0;
        return true;
    }

    /** The pose to show: the file's animation index and time, or null (the rest pose). */
    pose() {
        const a = this.current;
        return a ? { index: a.index, time: this.time } : null;
    }

    /** What the scripted API reports. */
    state() {
        const a = this.current;
        return { animations: this.list, chosen: this.chosen, name: a?.name ?? null, time: this.time, duration: a?.duration ?? 0, playing: this.playing };
    }
}

/**
 * The panel row: a list of the animations, play/pause, and a time slider.
 * @param {AnimationPlayer} player
 * @param {{row: HTMLElement, select: HTMLSelectElement, play: HTMLButtonElement, time: HTMLInputElement, label: HTMLElement}} ui
 * @param {() => void} changed  called when the pose changes by the user's hand
 */
export function bindAnimationUi(player, ui, changed) {
    ui.select.addEventListener('change', () => {
        player.choose(Number(ui.select.value));
        showAnimationUi(player, ui);
        changed();
    });
    ui.play.addEventListener('click', () => {
        if (!player.current) player.choose(0);
        player.playing = !player.playing;
        showAnimationUi(player, ui);
        changed();
    });
    ui.time.addEventListener('input', () => {
        if (!player.current) return;
        player.playing = false;
        player.seek(Number(ui.time.value) * player.current.duration);
        showAnimationUi(player, ui);
        changed();
    });
}

/**
 * Show the player's state in the panel row (hidden when the asset has no animation).
 * @param {AnimationPlayer} player
 * @param {{row: HTMLElement, select: HTMLSelectElement, play: HTMLButtonElement, time: HTMLInputElement, label: HTMLElement}} ui
 */
export function showAnimationUi(player, ui) {
    ui.row.hidden = player.list.length === 0;
    if (ui.select.options.length !== player.list.length + 1) {
        ui.select.replaceChildren();
        const none = document.createElement('option');
        none.value = '-1';
        none.textContent = 'rest pose';
        ui.select.append(none);
        player.list.forEach((a, i) => {
            const o = document.createElement('option');
            o.value = String(i);
            o.textContent = `${a.name} (${a.duration.toFixed(2)} s)`;
            ui.select.append(o);
        });
    }
    ui.select.value = String(player.chosen);
    ui.play.textContent = player.playing ? 'pause' : 'play';
    const a = player.current;
    ui.time.disabled = !a;
    ui.time.value = String(a && a.duration > 0 ? player.time / a.duration : 0);
    ui.label.textContent = a ? `${player.time.toFixed(2)} s` : '';
}
