// Render a DNG with the Adobe DNG SDK (the libdng that dngpy ships) to float32 RGB (ProPhoto
// primaries, linear tone curve) in the file's default crop: prints "width height planes" and
// writes the pixels, interleaved, to out.f32. Build: see benchmarks/dng_sdk_padding.py.
// Usage: sdk_render in.dng out.f32
#include "dng_host.h"
#include "dng_info.h"
#include "dng_negative.h"
#include "dng_render.h"
#include "dng_file_stream.h"
#include "dng_color_space.h"
#include "dng_image.h"
#include "dng_pixel_buffer.h"
#include "dng_memory.h"
#include "dng_exceptions.h"
#include <cstdio>
#include <cstring>
#include <vector>
int main(int argc, char **argv) {
  if (argc < 3) { fprintf(stderr, "usage: sdk_render in.dng out.f32\n"); return 2; }
  try {
    dng_file_stream stream(argv[1]);
    dng_host host;
    host.SetPreferredSize(0); host.SetMinimumSize(0); host.SetMaximumSize(0); host.ValidateSizes();
    dng_info info; info.Parse(host, stream); info.PostParse(host);
    if (!info.IsValidDNG()) { fprintf(stderr, "not a valid DNG\n"); return 3; }
    AutoPtr<dng_negative> negative(host.Make_dng_negative());
    negative->Parse(host, stream, info);
    negative->PostParse(host, stream, info);
    negative->ReadStage1Image(host, stream, info);
    negative->BuildStage2Image(host);
    negative->BuildStage3Image(host);
    dng_render render(host, *negative);
    render.SetFinalSpace(dng_space_ProPhoto::Get());
    render.SetFinalPixelType(ttFloat);
    render.SetToneCurve(dng_1d_identity::Get());
    AutoPtr<dng_image> final(render.Render());
    dng_rect area = final->Bounds();
    uint32 w = area.W(), h = area.H(), planes = final->Planes();
    dng_pixel_buffer buffer(area, 0, planes, ttFloat, pcInterleaved, nullptr);
    std::vector<float> data((size_t)w * h * planes);
    buffer.fData = data.data();
    final->Get(buffer);
    FILE *f = fopen(argv[2], "wb"); fwrite(data.data(), 4, data.size(), f); fclose(f);
    printf("%u %u %u\n", w, h, planes);
  } catch (const dng_exception &e) { fprintf(stderr, "dng_exception %d\n", e.ErrorCode()); return 4; }
  return 0;
}
