// Experiment: context switches and CPU per message of a bidi stream, callback API vs async API.
#include <dirent.h>
#include <grpcpp/grpcpp.h>
#include <sys/resource.h>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>
#include <vector>
#include "skinserve/v1/skinning.grpc.pb.h"
using namespace skinserve::v1;
using Clock = std::chrono::steady_clock;
static size_t g_resp = 64;
static int g_spin_us = 60;
static std::atomic<long> g_frames{0};
static void Spin() {
  auto end = Clock::now() + std::chrono::microseconds(g_spin_us);
  while (Clock::now() < end) {
  }
}
static long Switches() {
  long total = 0;
  DIR* d = opendir("/proc/self/task");
  while (dirent* e = readdir(d)) {
    if (e->d_name[0] == '.') continue;
    std::ifstream f(std::string("/proc/self/task/") + e->d_name + "/status");
    std::string line;
    while (std::getline(f, line))
      if (line.rfind("voluntary_ctxt_switches", 0) == 0 ||
          line.rfind("nonvoluntary_ctxt_switches", 0) == 0)
        total += std::stol(line.substr(line.find(':') + 1));
  }
  closedir(d);
  return total;
}
static double CpuS() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}
static SkinResponse MakeResp() {
  SkinResponse r;
  r.set_frame(1);
  if (g_resp > 64) r.set_positions(std::string(g_resp, 'x'));
  return r;
}

class CbService final : public Skinning::CallbackService {
  grpc::ServerBidiReactor<SkinRequest, SkinResponse>* StreamSkin(
      grpc::CallbackServerContext*) override {
    struct R : grpc::ServerBidiReactor<SkinRequest, SkinResponse> {
      SkinRequest req;
      SkinResponse resp = MakeResp();
      R() { StartRead(&req); }
      void OnReadDone(bool ok) override {
        if (!ok) {
          Finish(grpc::Status::OK);
          return;
        }
        Spin();
        resp.set_frame(req.frame());
        StartWrite(&resp);
      }
      void OnWriteDone(bool ok) override {
        if (!ok) {
          Finish(grpc::Status::OK);
          return;
        }
        g_frames++;
        StartRead(&req);
      }
      void OnDone() override { delete this; }
    };
    return new R;
  }
};

struct AsyncCall {
  enum St { kReq, kRead, kWrite, kFin } st = kReq;
  grpc::ServerContext ctx;
  grpc::ServerAsyncReaderWriter<SkinResponse, SkinRequest> rw{&ctx};
  SkinRequest req;
  SkinResponse resp = MakeResp();
  Skinning::AsyncService* svc;
  grpc::ServerCompletionQueue* cq;
  AsyncCall(Skinning::AsyncService* s, grpc::ServerCompletionQueue* q) : svc(s), cq(q) {
    svc->RequestStreamSkin(&ctx, &rw, cq, cq, this);
  }
  void Proceed(bool ok) {
    switch (st) {
      case kReq:
        if (!ok) {
          delete this;
          return;
        }
        new AsyncCall(svc, cq);
        st = kRead;
        rw.Read(&req, this);
        break;
      case kRead:
        if (!ok) {
          st = kFin;
          rw.Finish(grpc::Status::OK, this);
          break;
        }
        Spin();
        resp.set_frame(req.frame());
        st = kWrite;
        rw.Write(resp, this);
        break;
      case kWrite:
        if (!ok) {
          st = kFin;
          rw.Finish(grpc::Status::OK, this);
          break;
        }
        g_frames++;
        st = kRead;
        rw.Read(&req, this);
        break;
      case kFin:
        delete this;
        break;
    }
  }
};

int main(int argc, char** argv) {
  std::string mode = argv[1], addr = argv[2];
  if (argc > 3) g_resp = atol(argv[3]);
  if (mode == "client") {
    int streams = atoi(argv[4]);
    double secs = atof(argv[5]);
    auto ch = grpc::CreateChannel(addr, grpc::InsecureChannelCredentials());
    std::atomic<bool> stop{false};
    std::atomic<long> n{0};
    std::vector<std::thread> ts;
    for (int s = 0; s < streams; ++s)
      ts.emplace_back([&] {
        auto stub = Skinning::NewStub(ch);
        grpc::ClientContext ctx;
        auto rw = stub->StreamSkin(&ctx);
        SkinRequest req;
        req.set_palette(std::string(77 * 48, 'p'));
        SkinResponse resp;
        long f = 0;
        double rate = getenv("RATE") ? atof(getenv("RATE")) : 0;
        auto next = Clock::now() + std::chrono::microseconds(rand() % 16000);
        while (!stop) {
          if (rate > 0) {
            std::this_thread::sleep_until(next);
            next += std::chrono::microseconds(long(1e6 / rate));
          }
          req.set_frame(++f);
          rw->Write(req);
          if (!rw->Read(&resp)) break;
          n++;
        }
        rw->WritesDone();
        while (rw->Read(&resp)) {
        }
        rw->Finish();
      });
    std::this_thread::sleep_for(std::chrono::duration<double>(secs));
    stop = true;
    for (auto& t : ts) t.join();
    printf("client frames %ld\n", n.load());
    return 0;
  }
  int threads = argc > 4 ? atoi(argv[4]) : 1;
  if (getenv("HEALTH")) grpc::EnableDefaultHealthCheckService(true);
  grpc::ServerBuilder b;
  b.AddListeningPort(addr, grpc::InsecureServerCredentials());
  CbService cb;
  Skinning::AsyncService asvc;
  std::vector<std::unique_ptr<grpc::ServerCompletionQueue>> cqs;
  if (mode == "callback")
    b.RegisterService(&cb);
  else {
    b.RegisterService(&asvc);
    for (int i = 0; i < threads; ++i) cqs.push_back(b.AddCompletionQueue());
  }
  auto server = b.BuildAndStart();
  std::vector<std::thread> ts;
  for (auto& cq : cqs)
    ts.emplace_back([&asvc, q = cq.get()] {
      new AsyncCall(&asvc, q);
      void* tag;
      bool ok;
      while (q->Next(&tag, &ok)) static_cast<AsyncCall*>(tag)->Proceed(ok);
    });
  // report every 3 s
  long f0 = g_frames, s0 = Switches();
  double c0 = CpuS();
  for (int i = 0; i < 100; ++i) {
    std::this_thread::sleep_for(std::chrono::seconds(3));
    long f1 = g_frames, s1 = Switches();
    double c1 = CpuS();
    if (f1 > f0)
      printf("%s frames/s %.0f cpu us/frame %.1f switches/frame %.2f\n", mode.c_str(),
             (f1 - f0) / 3.0, 1e6 * (c1 - c0) / (f1 - f0), double(s1 - s0) / (f1 - f0));
    fflush(stdout);
    f0 = f1;
    s0 = s1;
    c0 = c1;
  }
}
