"""Pictures of episodes: the one top-down map (`topdown`), the one spectrogram picture
(`spectrogram`), their colours (`palette`) and the video frame built from them (`frames`).
`preview`, `view` and `evaluate --video` draw only through this package."""
