"""The neural-ISP task: a UNet learns RAW -> display sRGB on synthetic pairs and is tested on
the camera's real pairs (Graphics2RAW, Seo et al. ICCV 2023, Sec. 4.5).

- `pairs`: (packed RAW, sRGB target) pairs made from DNGs, real or synthetic, all the same way;
- `net`: the UNet, its training and the per-image PSNR, SSIM and CIEDE2000;
- `task`: the task itself (`run_isp_task`) over the training-set rows.

Layer: imports the shared base (`downstream.base`), never the other tasks.
"""
