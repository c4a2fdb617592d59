#include "rig_daemon/backends/phidget_interfacekit.h"

#include <libusb.h>

#include <algorithm>
#include <cmath>

namespace hc::rig::phidget {

std::uint32_t sensor_value(std::uint32_t raw12) {
  const double v =
      std::round(static_cast<double>(std::min<std::uint32_t>(raw12, 0xFFF)) * 1.001 / 4.095);
  return static_cast<std::uint32_t>(std::clamp(v, 0.0, 1000.0));
}

Result<InterfaceKitReport> decode_report(std::span<const std::uint8_t> b) {
  auto too_short = [&](std::size_t need, const char* what) {
    return invalid_argument("InterfaceKit report: " + std::to_string(b.size()) + " bytes, the " +
                            what + " need " + std::to_string(need));
  };
  if (b.size() < 3) return too_short(3, "header bytes");
  InterfaceKitReport r;
  r.packet_counter = static_cast<std::uint8_t>((b[0] >> 6) & 0x03);
  r.overcurrent = ((b[0] >> 5) & 0x01) != 0;
  r.ratiometric = ((b[0] >> 4) & 0x01) != 0;
  const unsigned overrun_bits = b[0] & 0x0Fu;
  for (int i = 0; i < 8; ++i) {
    r.inputs[i] = (b[1] & (1u << i)) == 0;  // inverted on the wire
    r.outputs[i] = (b[2] & (1u << i)) != 0;
  }
  std::size_t p = 3;
  for (int k = 0; k < 4; ++k) {
    if ((overrun_bits & (1u << k)) == 0) continue;
    if (p >= b.size()) return too_short(p + 1, "overrun bytes");
    r.overruns[2 * k] = static_cast<std::uint8_t>(b[p] >> 4);
    r.overruns[2 * k + 1] = static_cast<std::uint8_t>(b[p] & 0x0F);
    ++p;
  }
  if (p + 4 > b.size()) return too_short(p + 4, "count bytes");
  std::array<int, kSensors> count{};
  int total = 0;
  for (int i = 0; i < kSensors; ++i) {
    count[i] = (i % 2) != 0 ? (b[p + i / 2] & 0x0F) : (b[p + i / 2] >> 4);
    total += count[i];
  }
  p += 4;
  // 12-bit samples take 1.5 bytes each (rounded up for an odd total).
  const std::size_t need = p + (static_cast<std::size_t>(total) * 3 + 1) / 2;
  if (need > b.size()) return too_short(need, std::to_string(total).append(" samples").c_str());
  bool odd = false;
  for (int j = 0; total > 0; ++j) {
    for (int i = 0; i < kSensors; ++i) {
      if (count[i] <= j) continue;
      std::uint16_t v;
      if (!odd) {
        v = static_cast<std::uint16_t>(b[p] | ((b[p + 1] & 0xF0u) << 4));
        p += 2;
      } else {
        v = static_cast<std::uint16_t>(b[p] | ((b[p - 1] & 0x0Fu) << 8));
        p += 1;
      }
      r.raw[i].push_back(v);
      odd = !odd;
      --total;
    }
  }
  return r;
}

Result<std::vector<std::uint8_t>> encode_report(const InterfaceKitReport& r) {
  std::vector<std::uint8_t> b(3, 0);
  unsigned overrun_bits = 0;
  for (int k = 0; k < 4; ++k)
    if (r.overruns[2 * k] != 0 || r.overruns[2 * k + 1] != 0) overrun_bits |= 1u << k;
  b[0] = static_cast<std::uint8_t>(((r.packet_counter & 0x03) << 6) | (r.overcurrent ? 0x20 : 0) |
                                   (r.ratiometric ? 0x10 : 0) | overrun_bits);
  for (int i = 0; i < 8; ++i) {
    if (!r.inputs[i]) b[1] = static_cast<std::uint8_t>(b[1] | (1u << i));
    if (r.outputs[i]) b[2] = static_cast<std::uint8_t>(b[2] | (1u << i));
  }
  for (int k = 0; k < 4; ++k) {
    if ((overrun_bits & (1u << k)) == 0) continue;
    if (r.overruns[2 * k] > 15 || r.overruns[2 * k + 1] > 15)
      return invalid_argument("InterfaceKit report: an overrun count does not fit a nibble");
    b.push_back(static_cast<std::uint8_t>((r.overruns[2 * k] << 4) | r.overruns[2 * k + 1]));
  }
  std::size_t max_count = 0;
  for (int i = 0; i < kSensors; ++i) {
    if (r.raw[i].size() > 15)
      return invalid_argument("InterfaceKit report: sensor " + std::to_string(i) +
                              " has more than 15 samples");
    max_count = std::max(max_count, r.raw[i].size());
  }
  for (int m = 0; m < 4; ++m)
    b.push_back(static_cast<std::uint8_t>((r.raw[2 * m].size() << 4) | r.raw[2 * m + 1].size()));
  bool odd = false;
  for (std::size_t j = 0; j < max_count; ++j) {
    for (int i = 0; i < kSensors; ++i) {
      if (r.raw[i].size() <= j) continue;
      const std::uint16_t v = r.raw[i][j];
      if (v > 0xFFF) return invalid_argument("InterfaceKit report: sample above 12 bits");
      if (!odd) {
        b.push_back(static_cast<std::uint8_t>(v & 0xFF));
        b.push_back(static_cast<std::uint8_t>((v >> 4) & 0xF0));
      } else {
        b.back() = static_cast<std::uint8_t>(b.back() | (v >> 8));
        b.push_back(static_cast<std::uint8_t>(v & 0xFF));
      }
      odd = !odd;
    }
  }
  return b;
}

std::uint32_t PacketCounter::update(std::uint8_t counter) {
  counter &= 0x03;
  std::uint32_t lost = 0;
  if (have_) lost = static_cast<std::uint32_t>((counter - last_ - 1) & 0x03);
  have_ = true;
  last_ = counter;
  return lost;
}

// ---------------------------------------------------------------------------------------------

namespace {
libusb_context* as_ctx(void* p) { return static_cast<libusb_context*>(p); }
libusb_device_handle* as_handle(void* p) { return static_cast<libusb_device_handle*>(p); }
}  // namespace

Result<std::unique_ptr<InterfaceKitUsb>> InterfaceKitUsb::open(const std::string& serial) {
  std::unique_ptr<InterfaceKitUsb> kit(new InterfaceKitUsb());
  libusb_context* ctx = nullptr;
  if (const int rc = libusb_init(&ctx); rc != 0)
    return Status(StatusCode::kUnavailable,
                  std::string("Phidget InterfaceKit: libusb_init: ") + libusb_error_name(rc));
  kit->context_ = ctx;
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  if (n < 0)
    return Status(StatusCode::kUnavailable,
                  std::string("Phidget InterfaceKit: listing USB devices: ") +
                      libusb_error_name(static_cast<int>(n)));
  Status last_error = not_found("no Phidget InterfaceKit 8/8/8 (USB 06c2:0045) is connected" +
                                (serial.empty() ? std::string() : " with serial " + serial));
  for (ssize_t i = 0; i < n && kit->handle_ == nullptr; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != 0) continue;
    if (d.idVendor != kVendorId || d.idProduct != kInterfaceKit888ProductId) continue;
    libusb_device_handle* h = nullptr;
    if (const int rc = libusb_open(list[i], &h); rc != 0) {
      last_error = Status(StatusCode::kUnavailable,
                          std::string("Phidget InterfaceKit: open: ") + libusb_error_name(rc) +
                              " (a udev rule giving access to 06c2:0045 is needed)");
      continue;
    }
    unsigned char text[64] = {};
    std::string found_serial;
    if (d.iSerialNumber != 0 &&
        libusb_get_string_descriptor_ascii(h, d.iSerialNumber, text, sizeof text) > 0)
      found_serial = reinterpret_cast<const char*>(text);
    if (!serial.empty() && found_serial != serial) {
      libusb_close(h);
      continue;
    }
    kit->handle_ = h;
    kit->serial_ = found_serial;
    // The interrupt IN endpoint and its report size, from the configuration descriptor.
    libusb_config_descriptor* config = nullptr;
    if (libusb_get_active_config_descriptor(list[i], &config) == 0 && config->bNumInterfaces > 0 &&
        config->interface[0].num_altsetting > 0) {
      const libusb_interface_descriptor& alt = config->interface[0].altsetting[0];
      for (int e = 0; e < alt.bNumEndpoints; ++e) {
        const libusb_endpoint_descriptor& ep = alt.endpoint[e];
        if ((ep.bEndpointAddress & LIBUSB_ENDPOINT_IN) != 0 &&
            (ep.bmAttributes & 0x03) == LIBUSB_TRANSFER_TYPE_INTERRUPT) {
          kit->endpoint_ = ep.bEndpointAddress;
          kit->report_bytes_ = ep.wMaxPacketSize;
        }
      }
    }
    if (config != nullptr) libusb_free_config_descriptor(config);
  }
  libusb_free_device_list(list, 1);
  if (kit->handle_ == nullptr) return last_error;
  if (libusb_kernel_driver_active(as_handle(kit->handle_), 0) == 1) {
    if (libusb_detach_kernel_driver(as_handle(kit->handle_), 0) == 0) kit->reattach_ = true;
  }
  if (const int rc = libusb_claim_interface(as_handle(kit->handle_), 0); rc != 0)
    return Status(
        StatusCode::kUnavailable,
        std::string("Phidget InterfaceKit: claiming interface 0: ") + libusb_error_name(rc));
  return kit;
}

InterfaceKitUsb::~InterfaceKitUsb() {
  if (handle_ != nullptr) {
    libusb_release_interface(as_handle(handle_), 0);
    if (reattach_) libusb_attach_kernel_driver(as_handle(handle_), 0);
    libusb_close(as_handle(handle_));
  }
  if (context_ != nullptr) libusb_exit(as_ctx(context_));
}

Result<std::vector<std::uint8_t>> InterfaceKitUsb::read_report(int timeout_ms) {
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(std::max(report_bytes_, 8)));
  int got = 0;
  const int rc = libusb_interrupt_transfer(as_handle(handle_), endpoint_, buf.data(),
                                           static_cast<int>(buf.size()), &got, timeout_ms);
  if (rc == LIBUSB_ERROR_TIMEOUT) return std::vector<std::uint8_t>{};
  if (rc != 0)
    return Status(StatusCode::kUnavailable,
                  std::string("Phidget InterfaceKit: reading a report: ") + libusb_error_name(rc));
  buf.resize(static_cast<std::size_t>(got));
  return buf;
}

}  // namespace hc::rig::phidget
