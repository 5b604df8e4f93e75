"""The burst check's task: a denoiser trained on synthetic noisy/clean RAW, tested on the real
noisy frames of a burst (Graphics2RAW, Seo et al. ICCV 2023, Table 1).

- `bursts`: a burst's DNGs read into normalised CFA planes, its references and measured noise;
- `denoiser`: the residual CNN and its training;
- `noise`: each row's noise model and the synthetic noisy frames drawn from it;
- `burst_check`: the check itself (`run_burst_check`), its PSNRs and verdict.

Layer: imports the shared base (`downstream.base`), never the other tasks.
"""
