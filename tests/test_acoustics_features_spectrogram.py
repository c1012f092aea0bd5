"""SoundSpaces spectrogram and log-mel: shapes, an independent scipy-based reference, channel
order, and per-step windows (last second before the offset, zero-padded at the start)."""

from __future__ import annotations

import librosa
import numpy as np
import pytest
from scipy.signal import get_window, stft

from echo_data.acoustics.features import log_mel, soundspaces_spectrogram, step_features

FS = 16000


def ref_magnitude(x: np.ndarray) -> np.ndarray:
    """|STFT| (257, 101) with scipy: periodic Hann 400 centred in 512, hop 160, zero-padded centring."""
    win = np.zeros(512)
    win[56:456] = get_window("hann", 400)
    _, _, z = stft(x.astype(np.float64), window=win, nperseg=512, noverlap=512 - 160, boundary="zeros", padded=True)
    return np.abs(z) * win.sum()  # scipy scales by 1 / sum(window)


def ref_spectrogram(x2: np.ndarray) -> np.ndarray:
    out = np.zeros((65, 26, 2))
    for ch in range(2):
        mag = ref_magnitude(x2[:, ch])
        assert mag.shape == (257, 101)
        for i in range(65):
            for j in range(26):
                out[i, j, ch] = mag[4 * i : 4 * i + 4, 4 * j : 4 * j + 4].sum() / 16.0  # missing cells count as 0
    return np.log1p(out)


def signal(seed: int, n: int = FS) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    x = np.stack([np.sin(2 * np.pi * 700 * t) + 0.3 * rng.standard_normal(n), 0.5 * rng.standard_normal(n)], axis=1)
    return x.astype(np.float32)


def test_spectrogram_shape_and_independent_reference():
    x = signal(0)
    s = soundspaces_spectrogram(x)
    assert s.shape == (65, 26, 2) and s.dtype == np.float32
    np.testing.assert_allclose(s, ref_spectrogram(x), rtol=1e-4, atol=1e-4)


def test_spectrogram_channel_order_and_frequency_axis():
    t = np.arange(FS) / FS
    x = np.zeros((FS, 2), np.float32)
    x[:, 0] = np.sin(2 * np.pi * 1000 * t)  # left only
    s = soundspaces_spectrogram(x)
    assert np.all(s[..., 1] == 0.0) and s[..., 0].max() > 1.0
    assert int(np.argmax(s[:, 12, 0])) == 1000 // 31.25 // 4  # 1 kHz = STFT bin 32 = pooled row 8


def test_log_mel_shape_and_reference():
    x = signal(1)
    m = log_mel(x, FS, 64)
    assert m.shape == (64, 101, 2) and m.dtype == np.float32
    fb = librosa.filters.mel(sr=FS, n_fft=512, n_mels=64)
    for ch in range(2):
        ref = 10 * np.log10(np.maximum(fb @ ref_magnitude(x[:, ch]) ** 2, 1e-10))
        np.testing.assert_allclose(m[..., ch], ref, atol=2e-3)
    assert log_mel(x, FS, 40).shape == (40, 101, 2)


def test_log_mel_uses_the_last_second_zero_padded():
    x = signal(2, 3 * FS)
    np.testing.assert_array_equal(log_mel(x, FS, 32), log_mel(x[-FS:], FS, 32))
    short = x[:4000]
    padded = np.concatenate([np.zeros((FS - 4000, 2), np.float32), short])
    np.testing.assert_array_equal(log_mel(short, FS, 32), log_mel(padded, FS, 32))


def test_step_features_window_is_the_second_before_each_offset():
    track = signal(3, 6 * FS)
    offsets = np.arange(40) * 1600 + 800  # > one batch of steps
    spec, mel = step_features(track, offsets, FS, 48)
    assert spec.shape == (40, 65, 26, 2) and mel.shape == (40, 48, 101, 2)
    assert spec.dtype == np.float32 and mel.dtype == np.float32
    for i in (0, 5, 9, 10, 39):
        o = offsets[i]
        window = np.zeros((FS, 2), np.float32)
        lo = max(o - FS, 0)
        window[FS - (o - lo) :] = track[lo:o]
        np.testing.assert_allclose(spec[i], soundspaces_spectrogram(window), atol=1e-5)
        np.testing.assert_allclose(mel[i], log_mel(window, FS, 48), atol=1e-3)
    # causal and local: audio outside [offset - 1 s, offset) does not matter
    other = track.copy()
    other[: offsets[20] - FS] = 0.0
    other[offsets[20] :] = 1.0
    s2, m2 = step_features(other, offsets[20:21], FS, 48)
    np.testing.assert_array_equal(s2[0], spec[20])  # also: a step's bytes do not depend on the batch
    np.testing.assert_array_equal(m2[0], mel[20])


def test_step_features_at_episode_start_hear_silence():
    track = signal(4, 2 * FS)
    spec, mel = step_features(track, np.array([0]), FS, 64)
    assert np.all(spec == 0.0)
    assert np.all(mel == pytest.approx(-100.0))


def test_stft_and_filterbank_are_librosas_bit_for_bit():
    """The features compute librosa's STFT magnitudes and Slaney filterbank without librosa
    (no numba compile in every worker): same float32 values, not merely close ones."""
    from echo_data.acoustics.features import _stft_mag, mel_filterbank

    x = np.stack([signal(5, 7000).T, signal(6, 7000).T])  # (2, 2, n)
    ref = np.abs(librosa.stft(x, n_fft=512, hop_length=160, win_length=400, window="hann", center=True, pad_mode="constant"))
    assert np.array_equal(_stft_mag(x), ref)
    for fs, n_mels in ((16000, 64), (16000, 40), (44100, 64)):
        assert np.array_equal(mel_filterbank(fs, n_mels), librosa.filters.mel(sr=fs, n_fft=512, n_mels=n_mels))


@pytest.mark.parametrize("hop", [1600, 1234])
def test_feature_stream_equals_the_batch_on_the_finished_track(hop):
    """Step by step (frames of earlier steps reused when the hop allows) = `step_features` of the
    whole track, bit for bit, from the silent start on; a stream that re-analysed every frame would
    agree too, so the reuse is checked by counting the frames it keeps."""
    from echo_data.acoustics.features import FeatureStream, last_second

    track = signal(7, 5 * FS)
    offsets = np.arange(0, 40) * hop
    spec, mel = step_features(track, offsets, FS, 48)
    stream = FeatureStream(FS, 48)
    for i, o in enumerate(offsets):
        s, m = stream.features(last_second(track, o, FS), int(o))
        assert np.array_equal(s, spec[i]) and np.array_equal(m, mel[i]), i
    if hop == 1600:  # a step of 10 frames keeps 87 of the window's 97 interior frames from the last window
        assert stream.reused == 87 * (len(offsets) - 1)
