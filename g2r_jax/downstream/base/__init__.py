"""The shared base of the downstream tasks: what the illuminant, denoising and ISP checks all
train and test with, written once.

- `training`: the one training loop (equinox + optax: Adam, cosine decay, rounds, validation);
- `real_sets`: real test sets (the NUS thumbnails, a folder of a user's DNGs) and their labels;
- `thumbnails`: RAW mosaics and camera-RGB images -> small linear camera-RGB thumbnails;
- `training_sets`: synthetic training sets from CG views (UPI, g2r_jax) and the real controls;
- `upi`: UPI (Brooks et al. CVPR 2019), the baseline inverse ISP and its noise prior;
- `product`: g2r_jax as `g2r-fit-profile` makes it from real files (lights and content model);
- `cache`: the store of finished trainings; `progress`: the progress bar over planned trainings;
- `once`: work that threads share, done by the first that needs it;
- `figures`: a figure written as a PNG.

Layer: the bottom of `downstream`; it imports none of the task sub-packages (`illuminant`,
`denoising`, `isp`) nor the check above them (tests/test_layout.py).
"""
